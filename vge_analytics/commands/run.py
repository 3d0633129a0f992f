"""`vge run BENCH --agent AGENT --out RUN_DIR`: an agent plays the benchmark; the run directory
is what `vge replay` reads (docs/LIVE.md). With `--from RUN_DIR0 --at K|first-error [--fix]`,
a continuation run: each episode of RUN_DIR0 replayed up to the cut, then the agent's
(PROTOCOL §10.4).

Exit codes: 0 every selected episode was played; 2 some ended on an infrastructure failure
(see RUN_DIR/failures.jsonl; `--resume` plays them again), or the run stopped after
`--max-consecutive-failures` of them in a row (`--resume` continues); 1 fatal error (the
server checked before the first episode cannot serve the run, a request refused for good,
bad options), in one line.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import TYPE_CHECKING

import typer
from rich.console import Console
from rich.markup import escape
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from replay.io import FAILURES

from ._options import episode_ids, record_of
from ._output import finish

if TYPE_CHECKING:
    from vge_analytics.live import Counters


def _figures(counters: Counters, started: float, done_before: int) -> dict[str, str]:
    elapsed = max(time.monotonic() - started, 1e-9)
    rate = (counters.finished + counters.failures - done_before) / elapsed
    success = f"{100.0 * counters.succeeded / counters.finished:.1f}%" if counters.finished else "-"
    tokens = counters.prompt_tokens + counters.completion_tokens
    cost = counters.cost_usd
    return {
        "rate": f"{rate:.2f} ep/s",
        "success": f"success {success}",
        "failures": f"infra failures {counters.failures}" if counters.failures else "",
        "tokens": f"{tokens:,} tokens" if counters.has_usage else "",
        "cost": f"${cost:,.4f}" if cost is not None else "",
    }


def run_command(
    bench: Path = typer.Argument(..., help="Benchmark directory (ssm/, tasks.jsonl)."),
    agent: str = typer.Option(
        ...,
        "--agent",
        help="module:callable (agent(obs) -> text), sim:PROFILE (a profile of vge synth) or "
        "openai:MODEL (an OpenAI-compatible chat API).",
    ),
    out: Path = typer.Option(..., "--out", help="Run directory to write (run.json, episodes)."),
    episodes: str | None = typer.Option(
        None, "--episodes", help="Comma-separated episode ids (default: every task, in order)."
    ),
    limit: int | None = typer.Option(None, "--limit", min=0, help="Play the first N only."),
    concurrency: int = typer.Option(
        1, "--concurrency", min=1, help="Episodes played at once (threads)."
    ),
    history: int | None = typer.Option(
        None, "--history", min=0, help="Steps of history the agent keeps (default: all)."
    ),
    history_images: int | None = typer.Option(
        None,
        "--history-images",
        min=0,
        help="openai: of the steps kept, the latest J keep their picture (default: all; 0: "
        "text only, for servers that take one image per request).",
    ),
    lam: float | None = typer.Option(
        None, "--lambda", help="Budget factor of the run (default 5; a task's own wins)."
    ),
    run_id: str | None = typer.Option(None, "--run-id", help="Run id (default: RUN_DIR's name)."),
    model: str | None = typer.Option(None, "--model", help="Model name written in run.json."),
    agent_kind: str | None = typer.Option(
        None, "--agent-kind", help="vlm, human or scripted (default: from the agent)."
    ),
    resume: bool = typer.Option(
        False,
        "--resume",
        help="Complete the run in RUN_DIR (same settings as it was started), or extend it with "
        "more episodes (--limit, --episodes).",
    ),
    seed: int = typer.Option(0, "--seed", help="Seed of sim: agents."),
    base_url: str | None = typer.Option(
        None, "--base-url", help="openai: server address, e.g. http://127.0.0.1:8000/v1."
    ),
    temperature: float | None = typer.Option(None, "--temperature", help="openai: sampling."),
    max_tokens: int | None = typer.Option(None, "--max-tokens", min=1, help="openai: answer cap."),
    timeout: float = typer.Option(120.0, "--timeout", min=0.001, help="openai: s per request."),
    retries: int = typer.Option(4, "--retries", min=0, help="openai: retries of a request."),
    retry_wait: float = typer.Option(
        2.0,
        "--retry-wait",
        min=0.0,
        help="openai: s before the first retry (doubles, with jitter).",
    ),
    prompt_price: float | None = typer.Option(
        None, "--prompt-price", min=0.0, help="USD per million prompt tokens (for the cost)."
    ),
    completion_price: float | None = typer.Option(
        None, "--completion-price", min=0.0, help="USD per million completion tokens."
    ),
    max_consecutive_failures: int = typer.Option(
        10,
        "--max-consecutive-failures",
        min=0,
        help="Stop the run (exit 2, --resume continues) after N infrastructure failures in a "
        "row; 0: never.",
    ),
    progress: bool = typer.Option(True, "--progress/--no-progress", help="Progress bar on a TTY."),
    source: Path | None = typer.Option(
        None,
        "--from",
        help="A continuation run: continue the episodes of this run directory (with --at).",
    ),
    at: str | None = typer.Option(
        None,
        "--at",
        help="With --from: replay the first K steps of each episode, or every step before its "
        "first error (first-error), then hand it to the agent.",
    ),
    fix: bool = typer.Option(
        False,
        "--fix",
        help="With --from: play the planner's optimal step at the cut before the agent.",
    ),
) -> None:
    """Play the benchmark with an agent and write a run directory that `vge replay` reads."""
    params = dict(locals())  # the options, by name: they fill the records below
    from vge_analytics._errors import RunStoppedError
    from vge_analytics.live import (
        AgentOptions,
        ClientSettings,
        RunOptions,
        continuation_of,
        load_agent,
        run_live,
    )

    continuation = continuation_of(source, at, fix)
    client = record_of(ClientSettings, params)
    live_agent = load_agent(agent, record_of(AgentOptions, params, client=client))
    episode_list = episode_ids(episodes, "--episodes")
    options = record_of(RunOptions, params, episodes=episode_list, continuation=continuation)
    console = Console(stderr=True, highlight=False)
    bar = Progress(
        TextColumn("[bold]run[/] {task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("{task.fields[rate]}  {task.fields[success]}  {task.fields[failures]}"),
        TextColumn("{task.fields[tokens]}  {task.fields[cost]}"),
        TimeElapsedColumn(),
        console=console,
        disable=not (progress and console.is_terminal),
    )
    started = time.monotonic()
    state: dict[str, int] = {}

    def tick(counters: Counters) -> None:
        if "task" not in state:
            state["before"] = counters.finished + counters.failures
            state["task"] = bar.add_task(
                escape(live_agent.spec), total=counters.selected, **_figures(counters, started, 0)
            )
        bar.update(
            state["task"],
            completed=counters.finished + counters.failures + counters.skipped,
            **_figures(counters, started, state["before"]),
        )

    try:
        with bar:
            summary = run_live(live_agent, options, progress=tick)
    except KeyboardInterrupt:
        console.print(
            f"interrupted: the finished episodes are in {escape(str(out))}; the same command "
            "with --resume completes the run",
            soft_wrap=True,
        )
        raise typer.Exit(130) from None
    except RunStoppedError as exc:
        console.print(escape(str(exc)), soft_wrap=True)
        raise typer.Exit(2) from None
    c = summary.counters
    h = summary.header
    out_console = Console(highlight=False)
    rate = f"{100.0 * c.succeeded / c.finished:.1f}%" if c.finished else "-"
    line = f"{h.run_id}: {c.finished}/{c.selected} episodes, success {rate}, {c.steps} steps"
    if c.has_usage:
        line += f", {c.prompt_tokens} prompt + {c.completion_tokens} completion tokens"
    if c.cost_usd is not None:
        line += f", ${c.cost_usd:,.4f}"
    if c.context_exceeded:
        line += f", {c.context_exceeded} ended by the model's context window (context_exceeded)"
    if summary.extended_from is not None:
        line += f" (extended from {summary.extended_from} selected)"
    out_console.print(escape(line), soft_wrap=True)
    for reason in summary.skipped:
        out_console.print(f"[yellow]not playable[/]: {escape(reason)}", soft_wrap=True)
    wrote = f"wrote {escape(str(out))}; score it: vge replay {escape(str(out))} --bench {escape(str(bench))} --out OUT"
    failed = len(summary.failures)
    listed = escape(str(out / FAILURES))
    problem = f"{failed} episode(s) ended on an infrastructure failure[/] (see {listed}); --resume plays them again"
    finish(out_console, wrote, problem if failed else None)


def register(app: typer.Typer) -> None:
    app.command("run")(run_command)
