"""Live runs: `vge run` plays agents (module callables, simulated profiles, VLMs) through `vge/Device-v0`."""

from typing import TYPE_CHECKING

from replay import lazy_names

if TYPE_CHECKING:  # the names, imported when first used (`lazy_names`): the prompt alone
    # (`vge export`) does not load the OpenAI client
    from ._agent_spec import load_agent
    from ._agents import AgentOptions, EpisodeStart, LiveAgent, Player, Reply
    from ._continue import FIRST_ERROR, ContinueFrom, continuation_of
    from ._harness import RunSummary, run_live, select_episodes
    from ._header import Counters, RunOptions
    from ._openai import ChatClient, ClientSettings, Completion
    from ._prompt import SYSTEM_PROMPT, build_messages, observation_text
    from ._rundir import FAILURES, FailureRecord

__all__ = [
    "FAILURES",
    "FIRST_ERROR",
    "SYSTEM_PROMPT",
    "AgentOptions",
    "ChatClient",
    "ClientSettings",
    "Completion",
    "ContinueFrom",
    "continuation_of",
    "Counters",
    "EpisodeStart",
    "FailureRecord",
    "LiveAgent",
    "Player",
    "Reply",
    "RunOptions",
    "RunSummary",
    "build_messages",
    "load_agent",
    "observation_text",
    "run_live",
    "select_episodes",
]

__getattr__, __dir__ = lazy_names(__name__, __file__)
