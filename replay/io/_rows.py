"""The row class of each partitioned table: the layout's table names joined to the records of
`replay.semantics`, apart from the layout itself, which imports no table library (so that
`vge --help` and a metric file's check import none: docs/PERFORMANCE.md, "Start-up")."""

from __future__ import annotations

from ..semantics import EpisodeRow, GoalRow, StepRow
from ._layout import EPISODES_TABLE, GOALS_TABLE, STEPS_TABLE

TABLE_ROWS: dict[str, type] = {STEPS_TABLE: StepRow, EPISODES_TABLE: EpisodeRow, GOALS_TABLE: GoalRow}
"""The row class of each partitioned table (its columns, PROTOCOL §7.2-§7.4)."""
