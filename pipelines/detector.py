"""Open-vocabulary detection (transformers OWL-ViT / OWLv2 / Grounding DINO) and sidewalk segmentation, from paths."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from pipelines.common import PipelineError


def _check_local(model: str, what: str) -> str:
    import os

    # A hub name would hang on retries offline; only accept names when the hub is allowed.
    if not Path(model).exists() and os.environ.get("HF_HUB_OFFLINE") == "1":
        raise PipelineError(
            f"{what} {model!r} is not a local folder and HF_HUB_OFFLINE=1; download it (save_pretrained) to a folder "
            f"and set that path in params.yaml"
        )
    return model


class ZeroShotDetector:
    """Text-prompted box detector; every prompt is scored on every image in one forward pass."""

    def __init__(self, model: str, device: str = "cpu") -> None:
        from transformers import AutoModelForZeroShotObjectDetection, AutoProcessor

        path = _check_local(model, "detector model")
        self.processor = AutoProcessor.from_pretrained(path)
        self.model = AutoModelForZeroShotObjectDetection.from_pretrained(path).to(device).eval()
        self.device = device
        self.kind = self.model.config.model_type

    def detect(self, image: Any, prompts: list[str], threshold: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Boxes (n, 4) in pixels, scores (n,) and prompt indices (n,) above `threshold` for one PIL image."""
        import torch

        w, h = image.size
        if self.kind == "grounding-dino":
            text = ". ".join(prompts) + "."
            inputs = self.processor(images=image, text=text, return_tensors="pt").to(self.device)
            with torch.no_grad():
                out = self.model(**inputs)
            res = self.processor.post_process_grounded_object_detection(
                out, inputs.input_ids, threshold=threshold, text_threshold=threshold, target_sizes=[(h, w)]
            )[0]
            names = [str(x) for x in res.get("text_labels", res.get("labels"))]
            idx = np.array(
                [next((i for i, p in enumerate(prompts) if n and n in p), -1) for n in names], dtype=np.int64
            )
            keep = idx >= 0
            return res["boxes"].cpu().numpy()[keep], res["scores"].cpu().numpy()[keep], idx[keep]
        # OWL text towers have 16 positions; pad every prompt to that length as the original models do.
        inputs = self.processor(
            text=prompts, images=image, padding="max_length", truncation=True, return_tensors="pt"
        ).to(self.device)
        with torch.no_grad():
            out = self.model(**inputs)
        # OWLv2 pads images to a square before resizing, so boxes are relative to the padded square.
        side = max(h, w) if self.kind == "owlv2" else None
        size = (side, side) if side else (h, w)
        post = (
            getattr(self.processor, "post_process_object_detection", None)
            or self.processor.image_processor.post_process_object_detection
        )
        res = post(out, threshold=threshold, target_sizes=[size])[0]
        boxes = res["boxes"].cpu().numpy().astype(np.float64)
        boxes[:, [0, 2]] = boxes[:, [0, 2]].clip(0, w)
        boxes[:, [1, 3]] = boxes[:, [1, 3]].clip(0, h)
        return boxes, res["scores"].cpu().numpy().astype(np.float64), res["labels"].cpu().numpy().astype(np.int64)


class SidewalkSegmenter:
    """Semantic segmentation model (e.g. a Cityscapes-trained SegFormer) giving a boolean sidewalk mask."""

    def __init__(self, model: str, labels: list[str], device: str = "cpu") -> None:
        from transformers import AutoImageProcessor, AutoModelForSemanticSegmentation

        path = _check_local(model, "segmentation model")
        self.processor = AutoImageProcessor.from_pretrained(path)
        self.model = AutoModelForSemanticSegmentation.from_pretrained(path).to(device).eval()
        self.device = device
        id2label = {int(k): v for k, v in self.model.config.id2label.items()}
        self.ids = [i for i, name in id2label.items() if name in set(labels)]
        if not self.ids:
            raise PipelineError(
                f"segmentation model {model} has no class among {labels}; its classes are {sorted(id2label.values())}; "
                f"set detect.sidewalk_labels to its sidewalk class name"
            )

    def mask(self, image: Any) -> np.ndarray:
        """Boolean (h, w) mask of sidewalk pixels for one PIL image."""
        import torch

        inputs = self.processor(images=image, return_tensors="pt").to(self.device)
        with torch.no_grad():
            out = self.model(**inputs)
        seg = self.processor.post_process_semantic_segmentation(out, target_sizes=[image.size[::-1]])[0]
        return np.isin(seg.cpu().numpy(), self.ids)
