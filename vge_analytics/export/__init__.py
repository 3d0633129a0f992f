"""Exports of replayed runs to the formats transcript tools read: Inspect `.eval` logs and ATIF trajectories (`vge export`, docs/EXPORT.md)."""

from ._export import FORMATS, IMAGES, ExportSummary, Progress, export

__all__ = ["FORMATS", "IMAGES", "ExportSummary", "Progress", "export"]
