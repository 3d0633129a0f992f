"""The fast path: whole batches of episodes replayed to Arrow tables, proven identical to the reference.

`replay.io` replays each batch of `vge replay` with `replay_kernel` (and decodes inputs
with `nested_beyond`'s depth check); the benchmarks time it against the reference
(`benchmarks/`). `decode_line` decodes an episode line straight into the structs the
kernel reads (`LogLine`), for the lines it can prove msgspec decodes to the same values
(`decline_reason` says why it leaves a line to msgspec).
"""

from ._batch import BatchTables, EpisodeInput, replay_kernel
from ._json import nested_beyond
from ._logline import LogLine, decline_reason, decode_line
from ._text import parse_fields

__all__ = [
    "BatchTables",
    "EpisodeInput",
    "LogLine",
    "decline_reason",
    "decode_line",
    "nested_beyond",
    "parse_fields",
    "replay_kernel",
]
