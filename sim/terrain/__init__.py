"""Terrain: tiles joined by Wave Function Collapse (wfc), their heights (heights), and PyBullet runways (runway)."""
