"""Asset retrieval: sources, normalisation, multi-view rendering, encoders, scoring and curation into the catalog."""
