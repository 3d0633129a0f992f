"""The fast path: whole batches of episodes replayed to Arrow tables, proven identical to the reference.

Public for the benchmarks that time it against the reference (`benchmarks/`); the runner
reaches it through `replay.io`.
"""

from ._batch import EpisodeInput, replay_kernel
from ._text import parse_fields

__all__ = ["EpisodeInput", "parse_fields", "replay_kernel"]
