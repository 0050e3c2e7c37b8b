"""What each `--scorer` costs per asset on one CPU core: image encoding of the 3 scored views and one metadata text.

The aligned and imagenet scorers run with their shipped weights. No CLIP/BLIP/BLIP-2 weights can be downloaded
here, so those run at their real sizes with random weights built from the default configs (CLIP ViT-B/32 at
224 px, BLIP ITM ViT-B/16 at 384 px, BLIP-2 ITM ViT-g/14 + Q-Former at 224 px): the same arithmetic as the
released models, so the same time. Run: HF_HUB_OFFLINE=1 python benchmarks/scorer_costs.py [--skip-blip2]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

OUT = Path(__file__).parent / "results" / "retrieval"


def _views(n: int = 3, size: int = 160) -> list[np.ndarray]:
    import tempfile

    from retrieval.aligned.dataset import render_asset

    with tempfile.TemporaryDirectory() as tmp:
        images, _ = render_asset("bench", 0, 12, size, (15.0, 40.0), Path(tmp))
    return images[:n]


def _time(fn, repeats: int = 3) -> float:  # noqa: ANN001
    fn()  # warm-up: lazy imports, first-call allocations
    t0 = time.process_time()
    for _ in range(repeats):
        fn()
    return (time.process_time() - t0) / repeats


def _hf_encoder(kind: str):  # noqa: ANN202 - an encoder object around a randomly initialised full-size model
    import transformers

    from retrieval.encoders.blip import BlipEncoder
    from retrieval.encoders.clip import ClipEncoder

    if kind == "clip":
        enc = ClipEncoder.__new__(ClipEncoder)
        enc.model = transformers.CLIPModel(transformers.CLIPConfig()).eval()
        tok = transformers.CLIPTokenizer(vocab=_byte_vocab("clip"), merges=[])
        enc.processor = transformers.CLIPProcessor(image_processor=transformers.CLIPImageProcessor(), tokenizer=tok)
        enc.dim, enc.batch_size, enc.device = enc.model.config.projection_dim, 32, "cpu"
        return enc
    enc = BlipEncoder.__new__(BlipEncoder)
    if kind == "blip":
        enc.model = transformers.BlipForImageTextRetrieval(transformers.BlipConfig()).eval()
        size = 384
    else:
        cfg = transformers.Blip2Config(qformer_config={"use_qformer_text_input": True})
        enc.model = transformers.Blip2ForImageTextRetrieval(cfg).eval()
        size = 224
    proc = transformers.BlipImageProcessor(size={"height": size, "width": size})
    enc.processor = transformers.BlipProcessor(
        image_processor=proc, tokenizer=transformers.BertTokenizer(_byte_vocab("bert"))
    )
    enc.kind = enc.name = kind
    enc.dim, enc.batch_size, enc.device = enc.model.config.image_text_hidden_size, 16, "cpu"
    return enc


def _byte_vocab(style: str):  # noqa: ANN202 - a character vocabulary: tokenisation cost is negligible beside the model
    import string
    import tempfile

    chars = list(string.ascii_lowercase + string.digits + " .,-'")
    if style == "clip":
        from tokenizers import pre_tokenizers

        al = sorted(pre_tokenizers.ByteLevel.alphabet())
        return {t: i for i, t in enumerate(["<|startoftext|>", "<|endoftext|>", *al, *(c + "</w>" for c in al)])}
    path = Path(tempfile.mkdtemp()) / "vocab.txt"
    path.write_text("\n".join(["[PAD]", "[UNK]", "[CLS]", "[SEP]", "[MASK]", *chars, *(f"##{c}" for c in chars)]))
    return str(path)


def main() -> None:
    """Print and save ms per asset (3 views + 1 text) for each scorer, one thread."""
    import torch

    from retrieval.encoders.text import TextEncoder

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--skip-blip2", action="store_true", help="BLIP-2's ViT-g needs ~5 GB and a minute to build")
    a = ap.parse_args()
    torch.set_num_threads(1)
    views, text = _views(), ["a 2.1 m brown wood park bench with backrest and armrests"]
    te = TextEncoder(None)
    rows = []
    from retrieval.encoders.aligned import AlignedEncoder
    from retrieval.encoders.imagenet import ImageNetEncoder

    encoders = {
        "aligned": lambda: AlignedEncoder(te, threads=1),
        "imagenet": lambda: ImageNetEncoder(te, threads=1),
        "clip": lambda: _hf_encoder("clip"),
        "blip": lambda: _hf_encoder("blip"),
    }
    if not a.skip_blip2:
        encoders["blip2"] = lambda: _hf_encoder("blip2")
    for name, make in encoders.items():
        enc = make()
        img = _time(lambda e=enc: e.encode_images(views))
        txt = _time(lambda e=enc: e.encode_texts(text))
        params = (
            sum(p.numel() for p in enc.model.parameters())
            if hasattr(enc, "model") and hasattr(enc.model, "parameters")
            else None
        )
        rows.append(
            {
                "scorer": name,
                "ms_3_views": round(1000 * img, 1),
                "ms_text": round(1000 * txt, 1),
                "assets_per_s_core_scoring_only": round(1 / (img + txt), 2),
                "params_M": None if params is None else round(params / 1e6, 1),
            }
        )
        print(rows[-1], flush=True)
        del enc
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "scorer_costs.json").write_text(
        json.dumps(
            {"command": "HF_HUB_OFFLINE=1 python benchmarks/scorer_costs.py", "threads": 1, "rows": rows}, indent=2
        )
        + "\n"
    )


if __name__ == "__main__":
    main()
