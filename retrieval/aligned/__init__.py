"""The `aligned` image-text scorer: frozen image and text encoders joined by small heads trained on the procedural
library's renders (LiT-style, "locked-image tuning" with both towers locked and only the heads trained).

Data flow: `captions` (descriptions with attributes per procedural asset) + `features` (frozen per-view features:
EfficientNet-Lite0 pooled, OpenCV colour histograms, silhouette shape) -> `dataset` (renders of seeded variants,
training seeds disjoint from the evaluation's) -> `train` (the heads, a DVC stage) -> `retrieval/models/aligned.npz`
-> `retrieval.encoders.aligned.AlignedEncoder` (the `--scorer aligned` default). docs/retrieval.md explains it.
"""
