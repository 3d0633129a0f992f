"""The names of the files `vge replay` makes from ids and numbers: an episode's (an id of any
characters made into a name every file system takes, PROTOCOL §7.8), its MCAP file's, and a
batch's Parquet part. Here rather than beside the MCAP writer, so that the processes that
only name the files do not load the MCAP and protobuf libraries."""

from __future__ import annotations

import hashlib
import re
from urllib.parse import quote

_SAFE = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9._+@-]{0,199}$")
NAME_BYTES = 200
"""The longest file name made from an id. What the replay adds around it (the longest:
`<name>.L<line>.mcap.tmp.tmp`, or `episodes-run_id=<run_id>` in `.replay/trash`) stays
within the 255 bytes common file systems allow for a name."""
_DIGEST = 32
"""Hex digits of the sha256 of an id in a shortened name (128 bits: two ids never share one)."""


def safe_file_name(name: str) -> str:
    """A file name for an id (PROTOCOL §7.8): unchanged when harmless, else
    percent-encoded; a name that would pass `NAME_BYTES` keeps its first characters and
    ends with `=` and the sha256 of the whole id (no other name holds `=`), so it stays
    unique and the same on every run."""
    if _SAFE.match(name):
        return name
    encoded = _encoded(name)
    if len(encoded) <= NAME_BYTES:
        return encoded
    budget = NAME_BYTES - _DIGEST - 1
    head = ""
    for k, ch in enumerate(name[:budget]):  # whole characters, so that the head decodes
        piece = _encoded(ch) if k == 0 else quote(ch, safe="")
        if len(head) + len(piece) > budget:
            break
        head += piece
    return f"{head}={hashlib.sha256(name.encode()).hexdigest()[:_DIGEST]}"


def _encoded(name: str) -> str:
    encoded = quote(name, safe="")
    return "%2E" + encoded[1:] if encoded.startswith(".") else encoded


def mcap_file_name(episode_id: str) -> str:
    """The file name of an episode's MCAP in `OUT/mcap/<run_id>/` (PROTOCOL §7.8)."""
    return f"{safe_file_name(episode_id)}.mcap"


def part_name(index: int) -> str:
    """The Parquet part written for batch `index` of a run (per table)."""
    return f"part-{index:05d}.parquet"
