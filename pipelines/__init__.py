"""Staged data pipelines (DVC): closed-set lists, OpenStreetMap, street images -> description pool and distributions."""
