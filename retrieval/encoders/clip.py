"""`clip` image-text encoder through transformers' CLIPModel: a model folder (or a cached hub name), GPU when present.

No CLIP weights ship in any wheel: point `model` at a local folder holding config, weights and processor files
(e.g. a downloaded openai/clip-vit-base-patch32). Tests build a tiny model from a small CLIPConfig.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np


@lru_cache(maxsize=2)
def _load(model: str, device: str):  # noqa: ANN202 - (CLIPModel, CLIPProcessor), imported lazily
    from transformers import CLIPModel, CLIPProcessor

    try:
        proc = CLIPProcessor.from_pretrained(model)
        net = CLIPModel.from_pretrained(model).to(device).eval()
    except (OSError, ValueError) as exc:  # ValueError: huggingface_hub's HFValidationError on a bad repo id
        raise FileNotFoundError(
            f"CLIP model {model!r} could not be loaded offline ({exc.__class__.__name__}); download the weights "
            f"(e.g. openai/clip-vit-base-patch32) to a folder and pass `--clip-model FOLDER`, or use the "
            f"offline `imagenet` scorer"
        ) from None
    return net, proc


class ClipEncoder:
    """CLIP image and text embeddings (unit vectors in CLIP's joint space), batched."""

    name = "clip"

    def __init__(self, model: str, device: str | None = None, batch_size: int = 32) -> None:
        import torch

        looks_like_path = "/" not in model or model.startswith(("/", ".", "~")) or model.count("/") > 1
        if not Path(model).expanduser().exists() and looks_like_path:
            raise FileNotFoundError(
                f"CLIP model {model!r} is neither an existing folder nor a hub name "
                f"(owner/name); pass a weights folder with --clip-model"
            )
        model = str(Path(model).expanduser()) if Path(model).expanduser().exists() else model
        self.device = device or ("cuda" if torch.cuda.is_available() else "cpu")
        self.model_name = model
        self.model, self.processor = _load(str(model), self.device)
        self.dim = int(self.model.config.projection_dim)
        self.batch_size = batch_size

    @staticmethod
    def _as_tensor(out):  # noqa: ANN001, ANN205 - transformers 5 may return a model output instead of a tensor
        return out if hasattr(out, "norm") else getattr(out, "pooler_output", out[0])

    def encode_images(self, images: list[np.ndarray]) -> np.ndarray:
        """(n, dim) unit image embeddings for HxWx3 uint8 images."""
        import torch

        out = []
        for i in range(0, len(images), self.batch_size):
            inputs = self.processor(images=list(images[i : i + self.batch_size]), return_tensors="pt").to(self.device)
            with torch.inference_mode():
                feats = self._as_tensor(self.model.get_image_features(**inputs)).float()
            out.append(torch.nn.functional.normalize(feats, dim=-1).cpu().numpy())
        return np.concatenate(out).astype(np.float32) if out else np.zeros((0, self.dim), np.float32)

    def encode_texts(self, texts: list[str]) -> np.ndarray:
        """(n, dim) unit text embeddings in CLIP's space."""
        import torch

        out = []
        for i in range(0, len(texts), self.batch_size):
            inputs = self.processor(
                text=list(texts[i : i + self.batch_size]), return_tensors="pt", padding=True, truncation=True
            ).to(self.device)
            with torch.inference_mode():
                feats = self._as_tensor(self.model.get_text_features(**inputs)).float()
            out.append(torch.nn.functional.normalize(feats, dim=-1).cpu().numpy())
        return np.concatenate(out).astype(np.float32) if out else np.zeros((0, self.dim), np.float32)
