"""Seed derivation: every random decision draws from its own `random.Random`, seeded from
the run seed and the names of what is being generated (never from `hash()` of a str, never
from the global generator), so output does not depend on order or worker count."""

from __future__ import annotations

import hashlib
import random


def derive_seed(*parts: object) -> int:
    """A 64-bit seed from a tuple of names and numbers (stable across runs and machines)."""
    text = "\x1f".join(str(p) for p in parts)
    return int.from_bytes(hashlib.sha256(text.encode("utf-8")).digest()[:8], "big")


def rng_for(*parts: object) -> random.Random:
    """A private generator for one decision scope, e.g. `rng_for(seed, "device", device_id)`."""
    return random.Random(derive_seed(*parts))
