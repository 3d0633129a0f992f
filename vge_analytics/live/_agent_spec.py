"""The agent an AGENT argument of `vge run` names.

The kinds are imported when named: `sim:` brings in the synthetic benchmark, `openai:` the
client, and neither is needed for the other kinds.
"""

from __future__ import annotations

from .._errors import AgentError
from ._agents import AgentOptions, LiveAgent
from ._module import ModuleAgent, import_callable


def load_agent(spec: str, options: AgentOptions) -> LiveAgent:
    """The agent an AGENT argument names: `openai:MODEL`, `sim:PROFILE` or `module:callable`."""
    kind, sep, rest = spec.partition(":")
    if not sep or not kind or not rest:
        raise AgentError(f"agent {spec!r}: expected module:callable, sim:PROFILE or openai:MODEL")
    if kind == "openai":
        from ._vlm import OpenAIAgent

        return OpenAIAgent(rest, options)
    if kind == "sim":
        from ._sim import SimAgent

        return SimAgent(rest, options)
    return ModuleAgent(spec, import_callable(spec))


__all__ = ["load_agent"]
