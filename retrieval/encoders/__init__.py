"""Encoders that turn text and images into vectors (text: sentence-transformers; image: CLIP, ImageNet)."""
