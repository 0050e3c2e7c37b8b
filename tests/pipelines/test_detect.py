"""detect and describe: NMS, the sidewalk filter, manifest validation, a tiny OWLv2 end to end."""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image

from pipelines.boxes import nms, polygon_overlap
from pipelines.common import PipelineError
from pipelines.describe import colour_name, dominant_colour
from pipelines.detect import detect_images, read_manifest


def test_nms_keeps_best_of_overlapping_boxes():
    boxes = np.array([[0, 0, 10, 10], [1, 1, 11, 11], [50, 50, 60, 60], [0, 0, 10, 10.5]])
    scores = np.array([0.8, 0.9, 0.5, 0.7])
    assert nms(boxes, scores, 0.5).tolist() == [1, 2]
    assert nms(boxes, scores, 0.99).tolist() == [1, 0, 3, 2]


def test_polygon_overlap_uses_the_footprint():
    sidewalk = [
        __import__("shapely.geometry", fromlist=["Polygon"]).Polygon([(0, 80), (100, 80), (100, 100), (0, 100)])
    ]
    boxes = np.array([[10, 20, 20, 100], [30, 10, 40, 50], [50, 60, 60, 90]])
    ov = polygon_overlap(boxes, sidewalk, bottom_fraction=0.25)
    # Box 0 stands on the sidewalk, box 1 floats above it, box 2's bottom strip (82.5-90) is inside.
    assert ov.tolist() == pytest.approx([1.0, 0.0, 1.0])


def test_manifest_validation(tmp_path):
    m = tmp_path / "m.csv"
    m.write_text("path,lat\na.jpg,60.1\n")
    with pytest.raises(PipelineError, match="lacks column.*country, lon"):
        read_manifest(m)
    m.write_text("path,country,lat,lon\na.jpg,QQ,60.1,24.9\n")
    with pytest.raises(ValueError, match="'QQ' is not an ISO 3166-1"):
        read_manifest(m)


def test_colour_names():
    assert colour_name((200, 30, 30)) == "red" and colour_name((20, 120, 40)) == "green"
    assert colour_name((128, 128, 128)) == "gray" and colour_name((10, 10, 10)) == "black"
    patch = np.zeros((20, 20, 3), np.uint8)
    patch[:] = (30, 60, 200)
    assert dominant_colour(patch) == "blue"


@pytest.fixture(scope="module")
def tiny_detector(tmp_path_factory):
    from pipelines.detector import ZeroShotDetector
    from tests.pipelines.tiny_owl import build_tiny_owlv2

    return ZeroShotDetector(str(build_tiny_owlv2(tmp_path_factory.mktemp("owl"))))


def test_tiny_owlv2_end_to_end(tmp_path, tiny_detector):
    rng = np.random.default_rng(0)
    Image.fromarray((rng.random((60, 90, 3)) * 255).astype(np.uint8)).save(tmp_path / "a.png")
    (tmp_path / "b.jpg").write_bytes(b"not an image")
    ann = {
        "imgHeight": 60,
        "imgWidth": 90,
        "objects": [{"label": "sidewalk", "polygon": [[0, 40], [90, 40], [90, 60], [0, 60]]}],
    }
    (tmp_path / "a.json").write_text(json.dumps(ann))
    (tmp_path / "m.csv").write_text(
        "path,country,lat,lon,annotation\na.png,FI,60.17,24.94,a.json\nb.jpg,JP,35.6,139.7,\n"
    )
    man = read_manifest(tmp_path / "m.csv")
    prompts, cats = ["a bench", "a fire hydrant", "a street lamp"], ["bench", "fire_hydrant", "street_lamp"]
    dets, skipped, counts = detect_images(
        man,
        prompts,
        cats,
        tiny_detector,
        score_threshold=0.0,
        nms_iou=0.5,
        sidewalk_filter="auto",
        min_overlap=0.3,
        sidewalk_labels=["sidewalk"],
    )
    assert counts["images"] == 2 and counts["images_unreadable"] == 1 and skipped["image"].tolist() == ["b.jpg"]
    assert counts["boxes_raw"] >= counts["boxes_after_nms"] >= counts["detections"]
    assert counts["boxes_after_nms"] == counts["detections"] + counts["boxes_off_sidewalk"]
    assert len(dets) == counts["detections"]
    assert (dets["sidewalk_overlap"] >= 0.3).all() and set(dets["country"]) <= {"FI"}
    assert set(dets["category"]) <= set(cats)
