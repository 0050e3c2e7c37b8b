"""The ground every room stands on: config errors and checks (`kernel.config`), executors (`kernel.executors`),
quiet imports (`kernel.quiet`) and reproducible writes (`kernel.reproducible`). It imports no other room."""
