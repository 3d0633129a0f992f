"""Simulated agent profiles: the knobs of a noisy, feedback-driven device operator.

Each VLM-like profile mirrors one model of the paper's main table (named as a simulation,
`sim-vlm-a` ... `sim-vlm-f`); `sim-human` mirrors the human baseline. The numbers were tuned
on the full synthetic benchmark so the success rates at lambda = 5 and the error mix land near
the paper's (docs/SYNTHETIC.md has the measured values).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from ._rng import rng_for


@dataclass(frozen=True, slots=True)
class Profile:
    """How a simulated agent perceives, decides and formats."""

    name: str
    mimics: str
    """The paper's model (or the human baseline) this profile imitates."""
    agent_kind: str = "vlm"
    """`vlm` writes ReAct text; `human` logs structured actions."""

    # Grounding: where clicks land.
    sigma: float = 40.0
    """Click scatter around the intended point, on the 0..1000 scale (per axis, normal)."""
    gross_miss: float = 0.1
    """Chance a click lands somewhere unrelated (usually empty space)."""
    reground: float = 0.7
    """Scatter multiplier per remembered miss on the same component (learning to aim)."""

    # Knowledge.
    component_knowledge: float = 0.5
    """Chance of choosing a target component when one is visible."""
    action_knowledge: float = 0.7
    """Chance of the right atomic action for the chosen component."""
    param_knowledge: float = 0.6
    """Chance of the right parameters, given the right action."""
    wait_knowledge: float = 0.7
    """Chance of waiting when only waiting makes progress."""
    spurious_wait: float = 0.01
    """Chance of waiting when nothing is running."""
    explore_here: float = 0.3
    """Chance of trying a visible (wrong) component before switching views."""

    # Navigation.
    nav_skill: float = 0.6
    """Chance a needed view switch goes to a view showing a target."""
    wander: float = 0.04
    """Chance of switching away although a target is visible."""
    dashboard_skill: float = 0.6
    """Chance of unlocking the dashboard with an active unlock when it is needed."""
    axo_mistake: float = 0.3
    """Chance of trying to interact while in an axonometric view."""

    # Memory and learning.
    memory: float = 0.8
    """Chance of avoiding an attempt that is remembered to have failed."""
    history_length: int | None = None
    """Steps of history the agent keeps (None: the whole episode)."""
    feedback_use: float = 0.7
    """After 'operational_error', chance of changing the action or parameters, not the target."""

    # Output format.
    slip: float = 0.02
    """Chance of a format slip (unknown action, two actions, no action, malformed)."""
    decorated: float = 0.1
    """Chance of harmless decoration (bold, code fences, quotes) around the action."""

    # Timing of the synthetic timestamps (seconds per step: mean, spread).
    seconds: tuple[float, float] = (6.0, 2.5)

    def with_history(self, history_length: int | None) -> Profile:
        return replace(self, history_length=history_length)

    def on_device(self, difficulty: float) -> Profile:
        """The profile on a device `difficulty` logits harder (easier when negative): every
        skill's chance moved by that much on the logit scale, and the click scatter
        multiplied by exp(difficulty / 2). A chance of exactly 0 or 1 stays."""
        if difficulty == 0.0:
            return self
        moved = {name: _shift(getattr(self, name), -difficulty) for name in SKILLS}
        return replace(self, sigma=self.sigma * math.exp(difficulty / 2.0), **moved)


SKILLS: tuple[str, ...] = (
    "component_knowledge",
    "action_knowledge",
    "param_knowledge",
    "wait_knowledge",
    "nav_skill",
    "dashboard_skill",
    "memory",
    "feedback_use",
)
"""The chances a device's difficulty moves (`Profile.on_device`)."""
OWN_SHARE = 0.25
"""The share of a device's difficulty (in variance) that is the profile's own: the rest is
shared by every profile (a device hard for one is hard for all), this part makes profiles
differ by device."""


def _shift(p: float, logits: float) -> float:
    if p <= 0.0 or p >= 1.0:
        return p
    return 1.0 / (1.0 + math.exp(-(math.log(p / (1.0 - p)) + logits)))


def device_difficulty(seed: int, device_id: str, profile: str, spread: float) -> float:
    """How much harder a device is for a profile, in logits: `spread` times a standard
    normal mixing the device's shared difficulty and the profile's own on it
    (`OWN_SHARE`); seeded by the device (and the profile), so every run of a profile, its
    history variants and repetitions alike, meets the same difficulty. 0 when spread is 0."""
    if spread == 0.0:
        return 0.0
    shared = rng_for(seed, "difficulty", device_id).gauss(0.0, 1.0)
    own = rng_for(seed, "difficulty", device_id, profile).gauss(0.0, 1.0)
    return spread * (math.sqrt(1.0 - OWN_SHARE) * shared + math.sqrt(OWN_SHARE) * own)


PROFILES: tuple[Profile, ...] = (
    Profile(
        name="sim-vlm-a",
        mimics="MiMo-Embodied-7B",
        sigma=170.0,
        gross_miss=0.6,
        reground=0.95,
        component_knowledge=0.36,
        action_knowledge=0.5,
        param_knowledge=0.3,
        wait_knowledge=0.3,
        spurious_wait=0.03,
        explore_here=0.5,
        nav_skill=0.85,
        wander=0.01,
        dashboard_skill=0.3,
        axo_mistake=0.5,
        memory=0.1,
        feedback_use=0.2,
        slip=0.08,
        seconds=(3.0, 1.0),
    ),
    Profile(
        name="sim-vlm-b",
        mimics="InternVL3.5-8B-Instruct",
        sigma=95.0,
        gross_miss=0.3,
        reground=0.9,
        component_knowledge=0.33,
        action_knowledge=0.5,
        param_knowledge=0.4,
        wait_knowledge=0.4,
        spurious_wait=0.03,
        explore_here=0.45,
        nav_skill=0.5,
        wander=0.04,
        dashboard_skill=0.35,
        axo_mistake=0.4,
        memory=0.3,
        feedback_use=0.35,
        slip=0.05,
        seconds=(4.0, 1.5),
    ),
    Profile(
        name="sim-vlm-c",
        mimics="Qwen3-VL-8B-Instruct",
        sigma=80.0,
        gross_miss=0.25,
        reground=0.85,
        component_knowledge=0.44,
        action_knowledge=0.55,
        param_knowledge=0.45,
        wait_knowledge=0.5,
        spurious_wait=0.025,
        explore_here=0.4,
        nav_skill=0.5,
        wander=0.04,
        dashboard_skill=0.4,
        axo_mistake=0.35,
        memory=0.4,
        feedback_use=0.45,
        slip=0.04,
        seconds=(4.0, 1.5),
    ),
    Profile(
        name="sim-vlm-d",
        mimics="GPT-5-mini",
        sigma=90.0,
        gross_miss=0.4,
        reground=0.85,
        component_knowledge=0.68,
        action_knowledge=0.85,
        param_knowledge=0.7,
        wait_knowledge=0.6,
        spurious_wait=0.02,
        explore_here=0.35,
        nav_skill=0.6,
        wander=0.03,
        dashboard_skill=0.5,
        axo_mistake=0.25,
        memory=0.8,
        feedback_use=0.8,
        slip=0.02,
        seconds=(9.0, 3.0),
    ),
    Profile(
        name="sim-vlm-e",
        mimics="Doubao-1.5-Thinking-Vision-Pro",
        sigma=60.0,
        gross_miss=0.18,
        reground=0.8,
        component_knowledge=0.55,
        action_knowledge=0.65,
        param_knowledge=0.55,
        wait_knowledge=0.65,
        spurious_wait=0.02,
        explore_here=0.3,
        nav_skill=0.6,
        wander=0.03,
        dashboard_skill=0.55,
        axo_mistake=0.2,
        memory=0.55,
        feedback_use=0.55,
        slip=0.015,
        seconds=(12.0, 4.0),
    ),
    Profile(
        name="sim-vlm-f",
        mimics="Gemini-3-Flash",
        sigma=22.0,
        gross_miss=0.2,
        reground=0.7,
        component_knowledge=0.57,
        action_knowledge=0.97,
        param_knowledge=0.82,
        wait_knowledge=0.85,
        spurious_wait=0.01,
        explore_here=0.2,
        nav_skill=0.5,
        wander=0.05,
        dashboard_skill=0.75,
        axo_mistake=0.05,
        memory=0.85,
        feedback_use=0.8,
        slip=0.003,
        seconds=(7.0, 2.5),
    ),
    Profile(
        name="sim-human",
        mimics="Human Baseline",
        agent_kind="human",
        sigma=14.0,
        gross_miss=0.15,
        reground=0.6,
        component_knowledge=0.76,
        action_knowledge=0.96,
        param_knowledge=0.85,
        wait_knowledge=0.9,
        spurious_wait=0.01,
        explore_here=0.25,
        nav_skill=0.55,
        wander=0.04,
        dashboard_skill=0.85,
        axo_mistake=0.0,
        memory=0.95,
        feedback_use=0.9,
        slip=0.0,
        seconds=(11.0, 5.0),
    ),
)
"""The shipped profiles, weakest first."""

PROFILE_BY_NAME = {p.name: p for p in PROFILES}
STRONGEST_VLM = "sim-vlm-f"
