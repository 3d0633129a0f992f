"""What a step cost and where it came from (PROTOCOL §7.2, §7.3): tokens, latency and cost in
dollars from the run's prices, and the origin of a step of a continuation run.

One statement of each rule for every reader: the replay's session (step and episode rows),
the kernel (which computes the same numbers column by column, `replay.kernel._assemble`)
and the live harness's totals in run.json (`vge run`).
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

PROMPT_PRICE_KEY = "prompt_price_per_mtok"
COMPLETION_PRICE_KEY = "completion_price_per_mtok"
"""The keys of run.json's meta holding the prices, USD per million tokens (PROTOCOL §1.4)."""

MAX_PRICE = 1e6
"""The dearest price a run may give, USD per million tokens (PROTOCOL §1.4): a thousand times
any model's, and low enough that the costs of the largest token counts stay finite."""

ORIGINS = ("prefix", "fix", "agent")
"""A step's origin (PROTOCOL §7.2): repeated from the source run, the planner's fix, or the
run's own agent (every step of an ordinary run)."""


class Prices(NamedTuple):
    """USD per million prompt and completion tokens; None: not given."""

    prompt: float | None = None
    completion: float | None = None

    @property
    def known(self) -> bool:
        return self.prompt is not None or self.completion is not None


NO_PRICES = Prices()


def run_prices(meta: dict[str, Any]) -> Prices:
    """The prices a run.json's meta gives. A price that is not a non-negative number raises
    ValueError (the caller names the file)."""
    found = []
    for key in (PROMPT_PRICE_KEY, COMPLETION_PRICE_KEY):
        value = meta.get(key)
        if value is not None and (
            isinstance(value, bool)
            or not isinstance(value, (int, float))
            or not math.isfinite(value)
            or not 0 <= value <= MAX_PRICE
        ):
            raise ValueError(
                f"meta.{key} must be a number of USD from 0 to {MAX_PRICE:,.0f}, not {value!r}"
            )
        found.append(None if value is None else float(value))
    return Prices(*found)


def usage_cost(
    prompt_tokens: int | None, completion_tokens: int | None, prices: Prices
) -> float | None:
    """`(prompt tokens × prompt price + completion tokens × completion price) / 10^6`; a
    count or a price not given counts 0. None when no count is given or no price is known.

    The kernel computes the same expression with numpy (`_assemble.cost_column`): the same
    IEEE operations in the same order, so the same bits."""
    if (prompt_tokens is None and completion_tokens is None) or not prices.known:
        return None
    return (
        (prompt_tokens or 0) * (prices.prompt or 0.0)
        + (completion_tokens or 0) * (prices.completion or 0.0)
    ) / 1e6


def origin_of(k: int, prefix_steps: int, fixed: bool) -> str:
    """The origin of step `k` of an episode whose first `prefix_steps` steps are the source's
    and, when `fixed`, the next one the planner's."""
    if k < prefix_steps:
        return "prefix"
    if fixed and k == prefix_steps:
        return "fix"
    return "agent"
