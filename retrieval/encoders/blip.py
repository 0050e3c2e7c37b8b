"""`blip` and `blip2` image-text encoders through transformers' BlipForImageTextRetrieval and
Blip2ForImageTextRetrieval: a model folder (or a cached hub name), GPU when present.

Ranking uses the models' image-text contrastive (ITC) embeddings: BLIP's [CLS] projections; BLIP-2's Q-Former
query projections, where a view's similarity to a text is the best of its query tokens (as the model's own ITC
head computes it). `match_probability` is the image-text matching (ITM) head: a cross-attention pass per
(image, text) pair, too costly for a whole pool, used to check or re-rank a few candidates.

No BLIP weights ship in any wheel: point `model` at a local folder (e.g. a downloaded Salesforce/blip-itm-base-coco
or Salesforce/blip2-itm-vit-g). Tests build tiny models from configs.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np

KINDS = ("blip", "blip2")


@lru_cache(maxsize=2)
def _load(kind: str, model: str, device: str):  # noqa: ANN202 - (model, processor), imported lazily
    import transformers
    from transformers.utils import logging as hf_logging

    cls = transformers.BlipForImageTextRetrieval if kind == "blip" else transformers.Blip2ForImageTextRetrieval
    proc_cls = transformers.BlipProcessor if kind == "blip" else transformers.Blip2Processor
    verbosity = hf_logging.get_verbosity()
    hf_logging.set_verbosity_error()  # without torchvision the processors fall back to PIL, with a warning each load
    try:
        proc = proc_cls.from_pretrained(model)
        net = cls.from_pretrained(model).to(device).eval()
    except (OSError, ValueError) as exc:
        raise FileNotFoundError(
            f"{kind.upper()} model {model!r} could not be loaded offline ({exc.__class__.__name__}); download the "
            f"weights (e.g. Salesforce/blip-itm-base-coco) to a folder and pass `--clip-model FOLDER`, or use the "
            f"offline `aligned` scorer"
        ) from None
    finally:
        hf_logging.set_verbosity(verbosity)
    return net, proc


class BlipEncoder:
    """BLIP / BLIP-2 ITC embeddings (unit vectors), batched, and ITM match probabilities."""

    def __init__(self, model: str, kind: str = "blip", device: str | None = None, batch_size: int = 16) -> None:
        import torch

        if kind not in KINDS:
            raise ValueError(f"unknown BLIP kind {kind!r}; valid: {', '.join(KINDS)}")
        path = Path(model).expanduser()
        if not path.exists() and (model.startswith(("/", ".", "~")) or model.count("/") != 1):
            raise FileNotFoundError(
                f"{kind.upper()} model {model!r} is neither an existing folder nor a hub name "
                f"(owner/name); pass a weights folder with --clip-model"
            )
        self.name = kind
        self.kind = kind
        self.device = device or ("cuda" if torch.cuda.is_available() else "cpu")
        self.model, self.processor = _load(kind, str(path) if path.exists() else model, self.device)
        self.dim = int(self.model.config.image_text_hidden_size)
        self.batch_size = batch_size

    def _pixels(self, images: list[np.ndarray]):  # noqa: ANN202 - torch.Tensor
        return self.processor(images=list(images), return_tensors="pt")["pixel_values"].to(self.device)

    def _tokens(self, texts: list[str]):  # noqa: ANN202 - BatchEncoding
        return self.processor(text=list(texts), return_tensors="pt", padding=True, truncation=True).to(self.device)

    def image_tokens(self, images: list[np.ndarray]) -> np.ndarray:
        """(n, q, dim) unit ITC embeddings: q = 1 for BLIP ([CLS]), the Q-Former's query count for BLIP-2."""
        import torch
        from torch.nn.functional import normalize

        m, out = self.model, []
        for i in range(0, len(images), self.batch_size):
            with torch.inference_mode():
                hidden = m.vision_model(pixel_values=self._pixels(images[i : i + self.batch_size])).last_hidden_state
                if self.kind == "blip":
                    z = m.vision_proj(hidden[:, :1, :])
                else:
                    q = m.query_tokens.expand(hidden.shape[0], -1, -1)
                    att = torch.ones(hidden.shape[:-1], dtype=torch.long, device=hidden.device)
                    z = m.vision_projection(
                        m.qformer(
                            query_embeds=q, encoder_hidden_states=hidden, encoder_attention_mask=att
                        ).last_hidden_state
                    )
            out.append(normalize(z.float(), dim=-1).cpu().numpy())
        return np.concatenate(out).astype(np.float32) if out else np.zeros((0, 1, self.dim), np.float32)

    def encode_images(self, images: list[np.ndarray]) -> np.ndarray:
        """(n, dim) unit image embeddings (BLIP-2: the mean of its query embeddings, renormalised)."""
        z = self.image_tokens(images).mean(axis=1)
        return (z / np.maximum(np.linalg.norm(z, axis=1, keepdims=True), 1e-12)).astype(np.float32)

    def encode_texts(self, texts: list[str]) -> np.ndarray:
        """(n, dim) unit ITC text embeddings."""
        import torch
        from torch.nn.functional import normalize

        m, out = self.model, []
        for i in range(0, len(texts), self.batch_size):
            tok = self._tokens(texts[i : i + self.batch_size])
            with torch.inference_mode():
                if self.kind == "blip":
                    h = m.text_encoder(input_ids=tok["input_ids"], attention_mask=tok["attention_mask"])
                    z = m.text_proj(h.last_hidden_state[:, 0, :])
                else:
                    emb = m.embeddings(input_ids=tok["input_ids"])
                    h = m.qformer(query_embeds=emb, query_length=0, attention_mask=tok["attention_mask"])
                    z = m.text_projection(h.last_hidden_state[:, 0, :])
            out.append(normalize(z.float(), dim=-1).cpu().numpy())
        return np.concatenate(out).astype(np.float32) if out else np.zeros((0, self.dim), np.float32)

    def view_scores(self, images: list[np.ndarray], text_embeddings: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """((views, texts) ITC similarities, (views, dim) image embeddings): BLIP-2 takes each view's best query."""
        tokens = self.image_tokens(images)
        sims = np.einsum("vqd,td->vqt", tokens, text_embeddings).max(axis=1)
        z = tokens.mean(axis=1)
        return sims, (z / np.maximum(np.linalg.norm(z, axis=1, keepdims=True), 1e-12)).astype(np.float32)

    def match_probability(self, images: list[np.ndarray], texts: list[str]) -> np.ndarray:
        """(images, texts) ITM probability that each text describes each image (one cross-attention pass a pair)."""
        import torch

        out = np.zeros((len(images), len(texts)), dtype=np.float32)
        if not len(images) or not len(texts):
            return out
        tok = self._tokens(texts)
        for i, im in enumerate(images):
            pix = self._pixels([im]).expand(len(texts), -1, -1, -1)
            with torch.inference_mode():
                if self.kind == "blip":
                    logits = self.model(
                        input_ids=tok["input_ids"],
                        attention_mask=tok["attention_mask"],
                        pixel_values=pix,
                        use_itm_head=True,
                    ).itm_score
                else:
                    logits = self.model(
                        input_ids=tok["input_ids"],
                        attention_mask=tok["attention_mask"],
                        pixel_values=pix,
                        use_image_text_matching_head=True,
                    ).logits_per_image
            out[i] = torch.softmax(logits.float(), dim=-1)[:, 1].cpu().numpy()
        return out
