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
from typing import TYPE_CHECKING, Annotated

import typer

from replay import MAX_RECORD_BYTES
from replay.io import FAILURES

from ._options import episode_ids, record_of
from ._output import finish

if TYPE_CHECKING:
    from rich.console import Console
    from rich.progress import Progress

    from vge_analytics.live import Counters, LiveAgent, RunSummary

# The options, declared once each; the command's signature names them.
Bench = Annotated[Path, typer.Argument(help="Benchmark directory (ssm/, tasks.jsonl).")]
AgentSpec = Annotated[
    str,
    typer.Option(
        "--agent",
        help="module:callable (agent(obs) -> text), sim:PROFILE (a profile of vge synth) or "
        "openai:MODEL (an OpenAI-compatible chat API).",
    ),
]
RunDir = Annotated[Path, typer.Option("--out", help="Run directory to write (run.json, episodes).")]
Episodes = Annotated[
    str | None,
    typer.Option("--episodes", help="Comma-separated episode ids (default: every task, in order)."),
]
Limit = Annotated[int | None, typer.Option("--limit", min=0, help="Play the first N only.")]
Concurrency = Annotated[
    int, typer.Option("--concurrency", min=1, help="Episodes played at once (threads).")
]
History = Annotated[
    int | None,
    typer.Option("--history", min=0, help="Steps of history the agent keeps (default: all)."),
]
HistoryImages = Annotated[
    int | None,
    typer.Option(
        "--history-images",
        min=0,
        help="openai: of the steps kept, the latest J keep their picture (default: all; 0: "
        "text only, for servers that take one image per request).",
    ),
]
Lambda = Annotated[
    float | None,
    typer.Option("--lambda", help="Budget factor of the run (default 5; a task's own wins)."),
]
RunId = Annotated[str | None, typer.Option("--run-id", help="Run id (default: RUN_DIR's name).")]
Model = Annotated[str | None, typer.Option("--model", help="Model name written in run.json.")]
AgentKind = Annotated[
    str | None,
    typer.Option("--agent-kind", help="vlm, human or scripted (default: from the agent)."),
]
Resume = Annotated[
    bool,
    typer.Option(
        "--resume",
        help="Complete the run in RUN_DIR (same settings as it was started), or extend it with "
        "more episodes (--limit, --episodes).",
    ),
]
Seed = Annotated[int, typer.Option("--seed", help="Seed of sim: agents.")]
BaseUrl = Annotated[
    str | None,
    typer.Option("--base-url", help="openai: server address, e.g. http://127.0.0.1:8000/v1."),
]
Temperature = Annotated[float | None, typer.Option("--temperature", help="openai: sampling.")]
MaxTokens = Annotated[
    int | None, typer.Option("--max-tokens", min=1, help="openai: answer cap.")
]
Timeout = Annotated[
    float,
    typer.Option(
        "--timeout", min=0.001, help="openai: s per request, in all (not per read)."
    ),
]
MaxResponseBytes = Annotated[
    int,
    typer.Option(
        "--max-response-bytes",
        min=1024,
        max=MAX_RECORD_BYTES,
        metavar="BYTES",
        help="openai: the most one answer may take (4 MiB); a longer one is dropped, and retried.",
    ),
]
Retries = Annotated[int, typer.Option("--retries", min=0, help="openai: retries of a request.")]
RetryWait = Annotated[
    float,
    typer.Option(
        "--retry-wait", min=0.0, help="openai: s before the first retry (doubles, with jitter)."
    ),
]
PromptPrice = Annotated[
    float | None,
    typer.Option("--prompt-price", help="USD per million prompt tokens, 0 to 10^9 (for the cost)."),
]
CompletionPrice = Annotated[
    float | None,
    typer.Option("--completion-price", help="USD per million completion tokens, 0 to 10^9."),
]
MaxConsecutiveFailures = Annotated[
    int,
    typer.Option(
        "--max-consecutive-failures",
        min=0,
        help="Stop the run (exit 2, --resume continues) after N infrastructure failures in a "
        "row; 0: never.",
    ),
]
ShowProgress = Annotated[
    bool, typer.Option("--progress/--no-progress", help="Progress bar on a TTY.")
]
Source = Annotated[
    Path | None,
    typer.Option(
        "--from",
        help="A continuation run: continue the episodes of this run directory (with --at).",
    ),
]
At = Annotated[
    str | None,
    typer.Option(
        "--at",
        help="With --from: replay the first K steps of each episode, or every step before its "
        "first error (first-error), then hand it to the agent.",
    ),
]
Fix = Annotated[
    bool,
    typer.Option(
        "--fix", help="With --from: play the planner's optimal step at the cut before the agent."
    ),
]


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


def _progress_bar(console: Console, shown: bool) -> Progress:
    """The run's progress bar: episodes done, rate, success, failures, tokens, cost."""
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
    )

    return Progress(
        TextColumn("[bold]run[/] {task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("{task.fields[rate]}  {task.fields[success]}  {task.fields[failures]}"),
        TextColumn("{task.fields[tokens]}  {task.fields[cost]}"),
        TimeElapsedColumn(),
        console=console,
        disable=not (shown and console.is_terminal),
    )


def _play(live_agent: LiveAgent, options: object, out: Path, progress: bool) -> RunSummary:
    """Play the run with a progress bar on stderr; an interruption or a run stopped after too
    many failures in a row ends the command with its line (exit 130, 2)."""
    from rich.console import Console
    from rich.markup import escape

    from vge_analytics._errors import RunStoppedError
    from vge_analytics.live import run_live

    console = Console(stderr=True, highlight=False)
    bar = _progress_bar(console, progress)
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
            return run_live(live_agent, options, progress=tick)
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


def _summary_line(summary: RunSummary) -> str:
    """What the run did, in one line: episodes, success, steps, tokens, cost."""
    c = summary.counters
    rate = f"{100.0 * c.succeeded / c.finished:.1f}%" if c.finished else "-"
    line = f"{summary.header.run_id}: {c.finished}/{c.selected} episodes, success {rate}, {c.steps} steps"
    if c.has_usage:
        line += f", {c.prompt_tokens} prompt + {c.completion_tokens} completion tokens"
    if c.cost_usd is not None:
        line += f", ${c.cost_usd:,.4f}"
    if c.context_exceeded:
        line += f", {c.context_exceeded} ended by the model's context window (context_exceeded)"
    if summary.extended_from is not None:
        line += f" (extended from {summary.extended_from} selected)"
    return line


def _report(summary: RunSummary, bench: Path, out: Path) -> None:
    """The run's summary on stdout, what could not be played, and where to go next; exit 2
    when some episodes ended on an infrastructure failure."""
    from rich.console import Console
    from rich.markup import escape

    out_console = Console(highlight=False)
    out_console.print(escape(_summary_line(summary)), soft_wrap=True)
    for reason in summary.skipped:
        out_console.print(f"[yellow]not playable[/]: {escape(reason)}", soft_wrap=True)
    wrote = f"wrote {escape(str(out))}; score it: vge replay {escape(str(out))} --bench {escape(str(bench))} --out OUT"
    failed = len(summary.failures)
    listed = escape(str(out / FAILURES))
    problem = f"{failed} episode(s) ended on an infrastructure failure[/] (see {listed}); --resume plays them again"
    finish(out_console, wrote, problem if failed else None)


def run_command(
    bench: Bench,
    agent: AgentSpec,
    out: RunDir,
    episodes: Episodes = None,
    limit: Limit = None,
    concurrency: Concurrency = 1,
    history: History = None,
    history_images: HistoryImages = None,
    lam: Lambda = None,
    run_id: RunId = None,
    model: Model = None,
    agent_kind: AgentKind = None,
    resume: Resume = False,
    seed: Seed = 0,
    base_url: BaseUrl = None,
    temperature: Temperature = None,
    max_tokens: MaxTokens = None,
    timeout: Timeout = 120.0,
    max_response_bytes: MaxResponseBytes = 4 << 20,
    retries: Retries = 4,
    retry_wait: RetryWait = 2.0,
    prompt_price: PromptPrice = None,
    completion_price: CompletionPrice = None,
    max_consecutive_failures: MaxConsecutiveFailures = 10,
    progress: ShowProgress = True,
    source: Source = None,
    at: At = None,
    fix: Fix = False,
) -> None:
    """Play the benchmark with an agent and write a run directory that `vge replay` reads."""
    params = dict(locals())  # the options, by name: they fill the records below
    from vge_analytics.live import (
        AgentOptions,
        ClientSettings,
        RunOptions,
        continuation_of,
        load_agent,
    )

    continuation = continuation_of(source, at, fix)
    client = record_of(ClientSettings, params)
    live_agent = load_agent(agent, record_of(AgentOptions, params, client=client))
    episode_list = episode_ids(episodes, "--episodes")
    options = record_of(RunOptions, params, episodes=episode_list, continuation=continuation)
    summary = _play(live_agent, options, out, progress)
    _report(summary, bench, out)


def register(app: typer.Typer) -> None:
    app.command("run")(run_command)
