"""What the dashboard (`app/`) needs beyond the public analytics API, as tested functions.

The Streamlit pages stay thin: each calls these functions (and `metrics`, `error_distribution`,
`switch_classes`, `compare`, `sweep`, `sql`) through `st.cache_data`, keyed by the OUT path
and `out_version(out)`, the hash of OUT's manifest, so a re-replay invalidates every cached
result. Everything here reads the replay tables through the same locked-down DuckDB store
as the rest of the analytics (values are bound, never formatted into SQL).
"""

from __future__ import annotations

import hashlib
import io
import json
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import msgspec
import polars as pl

import replay

from ._errors import OutputDirError, UnknownRunError
from .metrics import Metric, MetricSet, MetricsSource, fingerprint, metric_set
from .reports import Rescore, group_label
from .store import (
    SLOT_WAIT,
    Filters,
    IsolatedResult,
    SqlLimits,
    build_scope,
    check_columns,
    format_size,
    open_store,
    quote_ident,
    resolve_input,
    run_isolated,
)
from .synth import image_source

DEFAULT_OUT = "logs-replayed"
"""Where `vge demo` writes the replayed bundled sample; `vge app` opens it by default."""
OUT_ENV = "VGE_APP_OUT"
"""Environment variable naming OUT for the app (set by `vge app`; `--out` wins)."""


# ------------------------------------------------------------------------------ OUT


def app_script() -> Path:
    """The Streamlit entry file `app/streamlit_app.py` (next to the package in the repo)."""
    here = Path(__file__).resolve().parent.parent / "app" / "streamlit_app.py"
    if here.is_file():
        return here
    import importlib.util

    spec = importlib.util.find_spec("app")
    if spec is not None and spec.submodule_search_locations:
        for base in spec.submodule_search_locations:
            candidate = Path(base) / "streamlit_app.py"
            if candidate.is_file():
                return candidate
    raise OutputDirError("the dashboard files (app/streamlit_app.py) are not installed")


def check_out(out: str | Path) -> Path:
    """OUT, resolved, if it is a replay output directory; else an error saying what to run."""
    shown = str(out)
    if replay.is_uri(shown):
        if not shown.startswith("file://"):  # opening it would reach the store: say so first
            raise OutputDirError(
                f"{shown}: the dashboard reads OUT on this machine (its viewer opens the "
                "episodes' files); copy OUT down first, or query it where it is with vge "
                "metrics, errors, compare, rescore, sweep and sql"
            )
        path = replay.location(shown).local
        assert path is not None  # a file:// URI names a local path
    else:
        path = Path(shown).expanduser()
    if not path.is_dir():
        hint = (
            "run `vge demo` first (it replays the bundled sample into ./logs-replayed)"
            if path.name == DEFAULT_OUT
            else f"run `vge demo`, or `vge replay RUN... --bench BENCH --out {shown}`, first"
        )
        raise OutputDirError(f"No replay output at {shown}: {hint}")
    missing = [t for t in ("steps", "episodes", "goals", "runs") if not (path / t).is_dir()]
    if missing or not (path / "manifest.json").is_file():
        what = ", ".join(f"{m}/" for m in missing) or "manifest.json"
        raise OutputDirError(
            f"{shown} is not a replay output directory (no {what}): run `vge replay RUN... "
            f"--bench BENCH --out {shown}` first"
        )
    return path.resolve()


def out_version(out: str | Path) -> str:
    """Content hash of OUT/manifest.json: the cache key of everything computed from OUT.

    A replay rewrites the manifest (input hashes, counts, engine version), so any change of
    the tables changes this value.
    """
    path = Path(out) / "manifest.json"
    try:
        data = path.read_bytes()
    except OSError:
        data = b""
    return hashlib.sha256(data).hexdigest()[:16]


@dataclass(frozen=True)
class OutSummary:
    """What the sidebar says about OUT."""

    out: str
    engine_version: str
    runs: int
    episodes: int
    steps: int
    quarantined: int
    benches: tuple[str, ...]


def out_summary(out: str | Path) -> OutSummary:
    """Counts and provenance of OUT from its manifest."""
    manifest = _manifest(out)
    totals = manifest.get("totals") or {}
    benches = sorted({r["inputs"]["bench"] for r in manifest.get("runs", []) if "inputs" in r})
    return OutSummary(
        out=str(out),
        engine_version=str(manifest.get("engine_version", "?")),
        runs=int(totals.get("runs", len(manifest.get("runs", [])))),
        episodes=int(totals.get("replayed", 0)),
        steps=int(totals.get("steps", 0)),
        quarantined=int(totals.get("quarantined", 0)),
        benches=tuple(benches),
    )


def _manifest(out: str | Path) -> dict:
    path = Path(out) / "manifest.json"
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise OutputDirError(f"{path}: unreadable manifest ({exc})") from None
    return data if isinstance(data, dict) else {}


def _run_entry(out: str | Path, run_id: str) -> dict:
    for entry in _manifest(out).get("runs", []):
        if entry.get("run_id") == run_id:
            return entry
    raise UnknownRunError(f"run {run_id!r} is not in {out}/manifest.json")


def bench_dir(out: str | Path, run_id: str | None = None) -> Path | replay.Location:
    """The benchmark directory a run (default: the first run) was replayed against."""
    runs = _manifest(out).get("runs", [])
    if not runs:
        raise OutputDirError(f"{out}: the manifest lists no run")
    entry = _run_entry(out, run_id) if run_id is not None else runs[0]
    bench = resolve_input(out, entry["inputs"]["bench"])
    if not bench.is_dir():
        raise OutputDirError(
            f"benchmark {entry['inputs']['bench']} (recorded in {out}/manifest.json) not found: "
            "start the app from the directory `vge replay` ran in"
        )
    return bench


# ---------------------------------------------------------------------------- facets


def column_values(out: str | Path, table: str, column: str) -> list:
    """Distinct non-null values of a scalar column of runs/episodes, sorted."""
    store = open_store(out)
    if table not in ("runs", "episodes"):
        raise OutputDirError(f"no value list for table {table!r}")
    check_columns(store, [column], [table], "filter")
    col = quote_ident(column)
    rows = (
        store.cursor()
        .execute(f"SELECT DISTINCT {col} FROM {table} WHERE {col} IS NOT NULL ORDER BY 1")
        .fetchall()
    )
    return [r[0] for r in rows]


# ------------------------------------------------------------------------- leaderboard


def group_labels(df: pl.DataFrame, by: Sequence[str]) -> pl.Series:
    """One readable label per row of a grouped result: the group values joined by ` · `.

    With run_id among the groups, model is left out (a run has one model).
    """
    cols = [c for c in by if not (c == "model" and "run_id" in by)]
    if not cols:
        return pl.Series("group", ["all"] * df.height, dtype=pl.String)
    exprs = [pl.col(c).cast(pl.String).fill_null("∅") for c in cols]
    label = exprs[0] if len(exprs) == 1 else pl.concat_str(exprs, separator=" · ")
    return df.select(label.alias("group")).to_series()


def _metric(name: str, metrics: MetricSet | None) -> Metric:
    return (metrics or MetricSet.builtin()).get(name)


def best_rows(
    df: pl.DataFrame, metric_names: Sequence[str], metrics: MetricSet | None = None
) -> dict[str, list[int]]:
    """{metric: row positions holding its best value}, by the metric's direction (the
    metrics of `metrics`, default the built-ins).

    Ties are all best; a column with no value has no best row.
    """
    best: dict[str, list[int]] = {}
    for name in metric_names:
        if name not in df.columns:
            continue
        values = df[name].to_list()
        present = [v for v in values if v is not None and not math.isnan(v)]
        if not present:
            best[name] = []
            continue
        target = max(present) if _metric(name, metrics).higher_is_better else min(present)
        best[name] = [i for i, v in enumerate(values) if v is not None and math.isclose(v, target)]
    return best


ORIGIN_MARKS: dict[str, str] = {"built-in": "", "override": " ✎", "added": " ＋"}
"""What a leaderboard header carries after its arrow: a metric a metrics folder overrides
(✎) or adds (＋)."""


def metric_headers(metric_names: Sequence[str], metrics: MetricSet | None = None) -> dict[str, str]:
    """{metric: header with the paper's arrow and its origin mark}, e.g. `SR ↑`, `VSPS ↓`,
    `SR ↑ ✎` (overridden by a metrics folder), `SR-multi ↑ ＋` (added by one)."""
    chosen = metrics or MetricSet.builtin()
    return {n: f"{n} {chosen.get(n).arrow}{ORIGIN_MARKS[chosen.origin(n)]}" for n in metric_names}


def metric_help(name: str, metrics: MetricSet | None = None) -> str:
    """The hover text of a metric's header: title, definition, and which file overrides or
    adds it."""
    chosen = metrics or MetricSet.builtin()
    m = chosen.get(name)
    origin = chosen.origin(name)
    text = f"{m.title}: {m.definition}"
    if origin == "override":
        text += f" (overrides the built-in {name}: {m.source}, version {m.version})"
    elif origin == "added":
        text += f" (added: {m.source}, version {m.version})"
    return text


def metrics_note(metrics: MetricSet | None) -> str | None:
    """What the pages say about a metrics folder (None without one): which metrics it
    overrides and adds, and how their headers are marked."""
    if metrics is None or metrics.folder is None:
        return None
    overridden = [m.name for m in metrics if metrics.origin(m.name) == "override"]
    added = [m.name for m in metrics if metrics.origin(m.name) == "added"]
    parts = []
    if overridden:
        parts.append(f"✎ overridden: {', '.join(overridden)}")
    if added:
        parts.append(f"＋ added: {', '.join(added)}")
    what = "; ".join(parts) if parts else "no metric changed"
    return f"Metrics of `{metrics.folder}`: {what}. Hover a header for its definition."


def metrics_long(
    df: pl.DataFrame, metric_names: Sequence[str], metrics: MetricSet | None = None
) -> pl.DataFrame:
    """A metrics table with a `group` column to long form (group, metric, value, direction),
    for one bar chart per metric; rows without a value are dropped."""
    present = [m for m in metric_names if m in df.columns]
    long = df.unpivot(index="group", on=present, variable_name="metric", value_name="value")
    directions = {m: _metric(m, metrics).direction for m in present}
    return long.drop_nulls("value").with_columns(
        direction=pl.col("metric").replace_strict(directions, return_dtype=pl.String)
    )


# ------------------------------------------------------------------------------ images


@dataclass(frozen=True)
class Box:
    """A component box on the 0..1000 scale of a view, with its role in the picture."""

    component: str
    x0: float
    y0: float
    x1: float
    y1: float
    role: str
    """`target` (a target component of the current state for the current goal), `hit`
    (hit by the click, not a target) or `component` (any other component of the view)."""


ROLE_COLORS: dict[str, tuple[int, int, int]] = {
    "target": (38, 191, 77),
    "hit": (255, 153, 0),
    "component": (120, 120, 120),
}
"""Box colours, as in the MCAP annotations: targets green, hits orange, others grey."""
CLICK_COLOR = (230, 26, 26)


@lru_cache(maxsize=64)
def _machine(ssm_path: str, device_id: str) -> replay.Machine:
    return replay.load_machine(ssm_path, device_id)


def device_machine(out: str | Path, device_id: str, run_id: str | None = None) -> replay.Machine:
    """The compiled SSM of a device, from the benchmark OUT was replayed against."""
    bench = bench_dir(out, run_id)
    path = bench / "ssm" / f"{device_id}.json"
    if not path.is_file():
        raise OutputDirError(f"{path}: SSM not found (the benchmark moved since the replay?)")
    return _machine(str(path), device_id)


def view_boxes(
    machine: replay.Machine,
    view: str,
    *,
    state: str | None = None,
    goal: str | None = None,
    hit: Sequence[str] = (),
    targets: Sequence[str] | None = None,
) -> list[Box]:
    """Every component box of `view`, each with its role.

    Targets are the target components of `state` for `goal` (PROTOCOL §4) drawn with their
    transitions' bboxes from that state, or, with `targets`, those components' boxes.
    """
    boxes: list[Box] = []
    target_names: set[str] = set()
    if targets is not None:
        target_names = set(targets)
    elif state is not None and goal is not None and state in machine.state_index:
        s, g = machine.state_index[state], machine.state_index.get(goal)
        if g is not None:
            for component, rect in replay.target_rects(machine, s, g, view):
                target_names.add(component)
                boxes.append(Box(component, *rect[:4], role="target"))
    hit_names = set(hit)
    for component, rect in machine.component_rects.get(view, ()):
        if targets is None and component in target_names:
            continue  # drawn with its state's target rects above
        role = (
            "target"
            if component in target_names
            else "hit"
            if component in hit_names
            else "component"
        )
        boxes.append(Box(component, *rect[:4], role=role))
    order = {"component": 0, "hit": 1, "target": 2}
    return sorted(boxes, key=lambda b: (order[b.role], b.component, b.x0, b.y0))


@dataclass(frozen=True)
class ViewPicture:
    """A device view image, as PNG/JPEG bytes with its pixel size (or a blank stand-in)."""

    data: bytes
    format: str
    width: int
    height: int
    rendered: bool
    """False when the benchmark has no image for the view (a blank canvas stands in)."""


def view_picture(
    out: str | Path, device_id: str, view: str, run_id: str | None = None
) -> ViewPicture:
    """The image of a device view (rendered synthetic views included), or a blank canvas."""
    bench = bench_dir(out, run_id)
    machine = device_machine(out, device_id, run_id)
    got = image_source(bench)(machine, view)
    if got is not None:
        return ViewPicture(*got, rendered=True)
    from PIL import Image

    buf = io.BytesIO()
    Image.new("RGB", (600, 600), (236, 238, 242)).save(buf, format="PNG")
    return ViewPicture(buf.getvalue(), "png", 600, 600, False)


def draw_step(
    picture: ViewPicture,
    boxes: Sequence[Box],
    click: tuple[float, float] | None,
    *,
    max_width: int = 720,
) -> bytes:
    """PNG of the view with the component boxes (by role) and the click drawn as a red x."""
    from PIL import Image, ImageDraw

    img = Image.open(io.BytesIO(picture.data)).convert("RGB")
    if img.width > max_width:
        img = img.resize((max_width, round(img.height * max_width / img.width)))
    sx, sy = img.width / replay.SCALE, img.height / replay.SCALE
    draw = ImageDraw.Draw(img)
    if not picture.rendered:
        draw.text((10, 10), "no image of this view in the benchmark", fill=(90, 90, 90))
    for box in boxes:
        width = {"target": 3, "hit": 3, "component": 1}[box.role]
        color = ROLE_COLORS[box.role]
        xy = (box.x0 * sx, box.y0 * sy, box.x1 * sx, box.y1 * sy)
        draw.rectangle(xy, outline=color, width=width)
        if box.role != "component" or not picture.rendered:
            draw.text((xy[0] + 3, xy[1] + 2), box.component, fill=color)
    if click is not None:
        cx, cy = click[0] * sx, click[1] * sy
        r = max(6.0, 0.015 * max(img.width, img.height))
        draw.line((cx - r, cy - r, cx + r, cy + r), fill=CLICK_COLOR, width=4)
        draw.line((cx - r, cy + r, cx + r, cy - r), fill=CLICK_COLOR, width=4)
    buf = io.BytesIO()
    img.save(buf, format="PNG")
    return buf.getvalue()


def step_picture(out: str | Path, run_id: str, episode_id: str, step: int) -> bytes:
    """The episode viewer's picture of one step: the view the agent saw, the click (red x),
    the components it hit (orange) and the target components of the current goal (green)."""
    from .store import steps

    rows = steps(out, where={"run_id": run_id, "episode_id": episode_id, "step": int(step)})
    if rows.height == 0:
        raise UnknownRunError(f"no step {step} in episode {episode_id!r} of run {run_id!r}")
    row = rows.row(0, named=True)
    view = row["view_before"]
    if view is None:
        raise OutputDirError(f"step {step} has no view (it was logged after the episode ended)")
    machine = device_machine(out, row["device_id"], run_id)
    picture = view_picture(out, row["device_id"], view, run_id)
    boxes = view_boxes(
        machine,
        view,
        state=row["state_before"],
        goal=row["goal_state"],
        hit=list(row["hit_components"] or []),
    )
    click = (row["x"], row["y"]) if row["x"] is not None and row["y"] is not None else None
    return draw_step(picture, boxes, click)


# -------------------------------------------------------------------------------- MCAP


def episode_mcap(out: str | Path, run_id: str, episode_id: str) -> bytes:
    """The episode's MCAP: OUT's file when the replay wrote one, else made now by replaying
    that one episode from the inputs the manifest records (same options, same bytes as
    `vge replay --mcap` would write)."""
    path = replay.episode_mcap_path(out, run_id, episode_id)
    if path.is_file():
        return path.read_bytes()
    entry = _run_entry(out, run_id)
    inputs = entry["inputs"]
    bench_root = bench_dir(out, run_id)
    bench = replay.Benchmark.open(bench_root)
    run_dir = resolve_input(out, inputs["run_dir"])
    header = replay.read_run_header(run_dir)
    log = _find_episode_log(replay.episodes_file(run_dir), episode_id)
    task = bench.tasks[episode_id].task
    machine = bench.machine(task.device_id)
    lam = replay.episode_lambda(task, header.lam, (entry.get("options") or {}).get("lambda"))
    result = replay.replay_episode(
        machine,
        task,
        log,
        lam=lam,
        run_id=header.run_id,
        model=header.model,
        agent_kind=header.agent_kind,
    )
    source = image_source(bench_root)
    buf = io.BytesIO()
    replay.write_episode_mcap(
        buf,
        machine,
        result,
        ssm_bytes=replay.attached_ssm(machine),
        image=lambda view: source(machine, view),
    )
    return buf.getvalue()


def _find_episode_log(path: Path, episode_id: str) -> replay.EpisodeLog:
    needle = json.dumps(episode_id).encode()
    for _, line in replay.iter_lines(path):
        if needle not in line:
            continue
        log = msgspec.json.decode(line, type=replay.EpisodeLog)
        if log.episode_id == episode_id:
            return log
    raise UnknownRunError(f"{path}: no episode {episode_id!r}")


# --------------------------------------------------------------------------- grounding


def interaction_views(out: str | Path, where: Filters = None) -> pl.DataFrame:
    """(device_id, category, view, interactions) for every device view clicked in, most
    clicked first: what the grounding scatter can show."""
    store = open_store(out)
    check_columns(store, list(where or {}), ["steps"], "filter")
    scope = build_scope(store, "steps", [], where)
    sql = (
        "SELECT g.device_id, g.category, g.view_before AS view, count(*) AS interactions "
        f"FROM {scope.from_sql} WHERE {scope.where_sql} AND g.is_interaction "
        "GROUP BY ALL ORDER BY interactions DESC, g.device_id, view"
    )
    return store.cursor().sql(sql, params=scope.params).pl()


def device_labels(views: pl.DataFrame) -> dict[str, str]:
    """{device_id: `<device> (<category>): <n> clicks`} of an `interaction_views` result, most
    clicked first."""
    per = views.group_by("device_id", "category", maintain_order=True).agg(
        pl.col("interactions").sum()
    )
    return {
        d: f"{d} ({c}): {n} clicks"
        for d, c, n in per.sort("interactions", descending=True, maintain_order=True).iter_rows()
    }


CLICK_OUTCOMES: tuple[str, ...] = ("target hit", "other component", "miss")
"""How a click point is coloured in the grounding scatter."""


def click_points(
    out: str | Path, device_id: str, view: str, where: Filters = None, *, limit: int = 5000
) -> pl.DataFrame:
    """Interactions on one device view: run_id, model, episode_id, step, x, y, outcome
    (`target hit`, `other component`, `miss`), error_type, distance, nearest_target."""
    store = open_store(out)
    check_columns(store, list(where or {}), ["steps"], "filter")
    scope = build_scope(store, "steps", [], where)
    sql = (
        "SELECT g.run_id, g.model, g.episode_id, g.step, g.x, g.y, "
        "CASE WHEN g.hit_target THEN 'target hit' WHEN g.hit_component THEN 'other component' "
        "ELSE 'miss' END AS outcome, g.error_type, g.distance, g.nearest_target "
        f"FROM {scope.from_sql} WHERE {scope.where_sql} AND g.is_interaction "
        "AND g.device_id = ? AND g.view_before = ? AND g.x IS NOT NULL AND g.y IS NOT NULL "
        "ORDER BY g.run_id, g.episode_id, g.step LIMIT ?"
    )
    params = [*scope.params, device_id, view, int(limit)]
    return store.cursor().sql(sql, params=params).pl()


def clicked_targets(points: pl.DataFrame) -> tuple[str, ...]:
    """The components that were the nearest target of some click of a `click_points` result."""
    return tuple(sorted(t for t in points["nearest_target"].unique().to_list() if t is not None))


def scatter_boxes(
    out: str | Path,
    device_id: str,
    view: str,
    targets: Sequence[str],
    run_id: str | None = None,
) -> pl.DataFrame:
    """The component boxes of a device view for the scatter: component, x0, y0, x1, y1 and
    role, `target` for the components named in `targets` (see `clicked_targets`)."""
    machine = device_machine(out, device_id, run_id)
    boxes = view_boxes(machine, view, targets=list(targets))
    return pl.DataFrame(
        [
            {
                "component": b.component,
                "x0": b.x0,
                "y0": b.y0,
                "x1": b.x1,
                "y1": b.y1,
                "role": b.role,
            }
            for b in boxes
        ],
        schema={
            "component": pl.String,
            "x0": pl.Float64,
            "y0": pl.Float64,
            "x1": pl.Float64,
            "y1": pl.Float64,
            "role": pl.String,
        },
    )


# ------------------------------------------------------------------------------ errors


def error_step_sample(
    out: str | Path,
    error_type: str,
    where: Filters = None,
    columns: Sequence[str] = ("run_id", "episode_id", "step"),
    *,
    limit: int = 500,
) -> tuple[pl.DataFrame, int]:
    """The first `limit` scored steps with `error_type` (by run, episode, step) and how many
    there are in all: the drill-down table. Unlike `steps_with_error`, the limit is applied
    in the query, so a common error type on the full benchmark (10^5 steps) stays cheap."""
    store = open_store(out)
    check_columns(store, [*(where or {}), *columns], ["steps"], "filter/column")
    order = "ORDER BY g.run_id, g.episode_id, g.step LIMIT ?"
    scope = build_scope(store, "steps", [], where)
    base = f"FROM {scope.from_sql} WHERE {scope.where_sql} AND g.error_type = ?"
    params = [*scope.params, error_type, int(limit)]
    total, runs = (
        store.cursor()
        .execute(
            f"SELECT (SELECT count(*) {base}), "
            f"(SELECT list(DISTINCT run_id) FROM (SELECT g.run_id {base} {order}))",
            [*params[:-1], *params],
        )
        .fetchall()[0]
    )
    # The wide columns are read from the runs of the first rows only: the scan skips the
    # other runs' files instead of reading every column of every step (same rows).
    scope = build_scope(store, "steps", [], {**(where or {}), "run_id": runs or []})
    cols = ", ".join(f"g.{quote_ident(c)}" for c in columns)
    base = f"FROM {scope.from_sql} WHERE {scope.where_sql} AND g.error_type = ?"
    df = store.cursor().sql(f"SELECT {cols} {base} {order}", params=[*scope.params, *params[-2:]])
    return df.pl(), int(total)


def error_share_wide(dist: pl.DataFrame) -> pl.DataFrame:
    """An `error_distribution(..., labels=True)` result with a `group` column as one row per
    group: `errors` (their number), then each error type's share in percent (paper names)."""
    from .reports import ERROR_LABELS, ERROR_TYPES

    labels = [ERROR_LABELS[t] for t in ERROR_TYPES]
    order = dist["group"].unique(maintain_order=True)
    totals = dist.group_by("group", maintain_order=True).agg(errors=pl.col("count").sum())
    wide = dist.pivot(on="label", index="group", values="share", aggregate_function="first")
    for label in labels:
        if label not in wide.columns:
            wide = wide.with_columns(pl.lit(None, dtype=pl.Float64).alias(label))
    return (
        pl.DataFrame({"group": order})
        .join(totals, on="group", how="left")
        .join(wide.select("group", *labels), on="group", how="left")
    )


# -------------------------------------------------------------------- small reshapings


def runs_matching(runs: pl.DataFrame, filters: Mapping[str, Sequence[object]]) -> list[str]:
    """Run ids of a `runs` table whose columns take one of the filter values (run columns
    only; a filter on another column is ignored here)."""
    mask = pl.lit(True)
    for column, values in filters.items():
        if column in runs.columns and values:
            wanted = list(values)
            cond = pl.col(column).is_in([v for v in wanted if v is not None])
            if any(v is None for v in wanted):
                cond = cond | pl.col(column).is_null()
            mask = mask & cond
    return runs.filter(mask)["run_id"].to_list()


def switch_summary(classes: pl.DataFrame, ratios: pl.DataFrame) -> pl.DataFrame:
    """One row per group: switches, the NP/PN/NN/PP shares (%), VSPS and GVPE.

    `classes` is a `switch_classes` result and `ratios` a `metrics(..., ["VSPS", "GVPE"])`
    result, both with a `group` column."""
    from .reports import SWITCH_CLASSES

    wide = classes.pivot(
        on="switch_class", index="group", values="share", aggregate_function="first"
    )
    counts = classes.group_by("group", maintain_order=True).agg(switches=pl.col("switches").first())
    for name in SWITCH_CLASSES:
        if name not in wide.columns:
            wide = wide.with_columns(pl.lit(None, dtype=pl.Float64).alias(name))
    return (
        ratios.select("group", "VSPS", "GVPE")
        .join(counts, on="group", how="left")
        .join(
            wide.select("group", *[pl.col(c).alias(f"{c} %") for c in SWITCH_CLASSES]),
            on="group",
            how="left",
        )
        .select("group", "switches", *[f"{c} %" for c in SWITCH_CLASSES], "VSPS", "GVPE")
    )


def click_counts(points: pl.DataFrame) -> dict[str, int]:
    """{outcome: clicks} of a `click_points` result, every outcome present."""
    counts = dict.fromkeys(CLICK_OUTCOMES, 0)
    for outcome, n in points.group_by("outcome").len().iter_rows():
        counts[outcome] = int(n)
    return counts


def sweep_curves(sweep: pl.DataFrame, *, relative: bool = False) -> pl.DataFrame:
    """A `sweep` result as the budget figure's lines: group (the run), lambda, SR and `gain`
    (`SR_gain` in percentage points, or `SR_rel_gain` in percent with `relative`)."""
    column = "SR_rel_gain" if relative else "SR_gain"
    return sweep.select(
        pl.col("run_id").alias("group"), "lambda", "SR", pl.col(column).alias("gain")
    )


# ----------------------------------------------------------------------- human vs VLM


def run_choices(runs: pl.DataFrame) -> tuple[list[str], list[str]]:
    """(reference runs, model runs) for the human-vs-VLM page: human runs first as the
    reference (all runs if there is none), non-human runs as the models, the most successful
    first, as the paper compares its best model (all runs if there is none).

    `runs` is a `runs()` table (with n_success and n_episodes)."""
    ranked = runs.with_columns(
        __rate=pl.col("n_success") / pl.when(pl.col("n_episodes") > 0).then(pl.col("n_episodes"))
    ).sort(["__rate", "run_id"], descending=[True, False], nulls_last=True)
    human = ranked.filter(pl.col("agent_kind") == "human")["run_id"].to_list()
    other = ranked.filter(pl.col("agent_kind") != "human")["run_id"].to_list()
    everything = ranked["run_id"].to_list()
    return (human + other if human else everything), (other or everything)


def comparison_rows(
    metrics: pl.DataFrame, label_a: str, label_b: str, metric_set: MetricSet | None = None
) -> pl.DataFrame:
    """A `Comparison.metrics` table for people: metric (with its arrow), both values under
    the runs' names, the difference B - A, its 95% interval, and whether the interval
    excludes 0."""
    arrows = {m: _metric(m, metric_set).arrow for m in metrics["metric"].to_list()}
    return metrics.select(
        pl.col("metric").map_elements(lambda m: f"{m} {arrows[m]}", return_dtype=pl.String),
        pl.col("A").alias(label_a),
        pl.col("B").alias(label_b),
        pl.col("diff").alias(f"{label_b} − {label_a}"),
        pl.col("ci_low").alias("CI low"),
        pl.col("ci_high").alias("CI high"),
        ((pl.col("ci_low") > 0) | (pl.col("ci_high") < 0)).alias("CI excludes 0"),
    )


def error_difference_rows(errors: pl.DataFrame, label_a: str, label_b: str) -> pl.DataFrame:
    """A `Comparison.errors` table like the paper's: error type, share of all errors of each
    run (%), and the difference B - A in percentage points."""
    return errors.select(
        pl.col("label").alias("error type"),
        pl.col("share_a").alias(f"{label_a} %"),
        pl.col("share_b").alias(f"{label_b} %"),
        pl.col("diff_pp").alias("difference (pp)"),
        pl.col("count_a").alias(f"{label_a} errors"),
        pl.col("count_b").alias(f"{label_b} errors"),
    )


def flip_rows(flips: pl.DataFrame, run_a: str, run_b: str) -> pl.DataFrame:
    """`Comparison.flips` with who solved the episode and `run_id`, the run that failed it
    (what the link opens: where it went wrong)."""
    return flips.select(
        "episode_id",
        "device_id",
        "category",
        pl.when(pl.col("direction") == "A_only")
        .then(pl.lit(run_a))
        .otherwise(pl.lit(run_b))
        .alias("solved only by"),
        pl.when(pl.col("direction") == "A_only")
        .then(pl.lit(run_b))
        .otherwise(pl.lit(run_a))
        .alias("run_id"),
    )


# ---------------------------------------------------------------------- episode viewer


TERMINATION_LABELS: dict[str, str] = {
    "success": "success",
    "budget_global": "global budget out",
    "budget_local": "local budget out",
    "log_ended": "log ended",
    "context_exceeded": "context window full",
}


def termination_label(termination: str) -> str:
    """How an episode ended, in words."""
    return TERMINATION_LABELS.get(termination, termination)


def episode_labels(episodes: pl.DataFrame) -> dict[str, str]:
    """{episode_id: `<id> · <device> · <how it ended> · <done>/<goals> goals`} for a picker
    (computed once for all episodes: a full-scale run has 10^4 of them)."""
    ended = pl.col("termination").replace_strict(
        TERMINATION_LABELS, default=pl.col("termination"), return_dtype=pl.String
    )
    label = pl.format(
        "{} · {} · {} · {}/{} goals",
        "episode_id",
        "device_id",
        ended,
        "goals_completed",
        "n_goals",
    )
    return dict(episodes.select("episode_id", label.alias("label")).iter_rows())


def _code(text: object) -> str:
    """Inline code that survives any text (backticks inside are widened around)."""
    value = str(text).replace("\n", " ")
    fence = "``" if "`" in value else "`"
    return f"{fence} {value} {fence}" if fence == "``" else f"`{value}`"


def step_caption(row: Mapping[str, object]) -> str:
    """Caption under the step picture: view, click, and what the colours mean."""
    click = (
        f"click ({row['x']:g}, {row['y']:g})"
        if row.get("x") is not None and row.get("y") is not None
        else "no click"
    )
    return (
        f"view {row['view_before']} · {click} · red x: click, green: target components, "
        "orange: components hit, grey: other components"
    )


def step_markdown(row: Mapping[str, object], goals: pl.DataFrame) -> str:
    """The step as the agent lived it: goal and instruction, action, feedback, state, view,
    budgets left (markdown; every free text in code spans)."""
    lines = [f"**Step {row['step']}**"]
    gi = row.get("goal_index")
    if gi is not None:
        goal = goals.filter(pl.col("goal_index") == gi)
        n = goals.height
        instruction = goal["instruction"][0] if goal.height else None
        lines.append(
            f"**Goal** {int(gi) + 1}/{n}: {_code(row['goal_state'])}"
            + (f" — {_code(instruction)}" if instruction else "")
        )
    lines.append(f"**Action** {_code(row['action_raw'])}")
    if not row.get("parse_ok"):
        lines.append(f"parse failure: {_code(row.get('parse_detail'))}")
    if row.get("truncated"):
        lines.append("*logged after the episode ended: not replayed, not scored*")
        return "  \n".join(lines)
    lines.append(f"**Feedback** ({row['feedback_kind']}) {_code(row['feedback_text'])}")
    entered = list(row.get("states_entered") or [])
    state = f"{_code(row['state_before'])} → {_code(row['state_after'])}"
    if len(entered) > 1:
        state += " via " + " → ".join(_code(s) for s in entered)
    if row.get("dangerous"):
        state += " · **dangerous** (entered an error state)"
    lines.append(f"**State** {state}")
    view = f"{row['view_before']} → {row['view_after']}"
    if row.get("dashboard_unlocked"):
        view += " · dashboard unlocked"
    lines.append(f"**View** {view}")
    lines.append(
        f"**Budgets left** global {row['budget_global_left']:g}, local {row['budget_local_left']:g}"
    )
    if row.get("diverged"):
        lines.append(f"**Diverged** from the log in {', '.join(row['diverged_fields'] or [])}")
    return "  \n".join(lines)


CLASSIFICATION_FIELDS: tuple[str, ...] = (
    "error_type",
    "error_detail",
    "error_group",
    "progress",
    "is_interaction",
    "hit_component",
    "hit_target",
    "hit_components",
    "nearest_target",
    "distance",
    "weight",
    "dist_before",
    "dist_after",
    "switch_class",
    "repetitive",
    "eer_valid",
    "completed_goals",
)
"""The step's classification (PROTOCOL §5) as the viewer lists it."""


def step_classification(row: Mapping[str, object]) -> pl.DataFrame:
    """The classification of a step as (field, value) rows, values as text (null as —)."""

    def text(value: object) -> str:
        if value is None:
            return "—"
        if isinstance(value, float):
            return f"{value:.1f}"
        if isinstance(value, list):
            return ", ".join(map(str, value)) or "—"
        return str(value)

    return pl.DataFrame(
        {
            "field": list(CLASSIFICATION_FIELDS),
            "value": [text(row.get(f)) for f in CLASSIFICATION_FIELDS],
        }
    )


# --------------------------------------------------------------------------------- SQL

EXAMPLE_QUERIES: dict[str, str] = {
    "Success rate and steps per model": (
        "SELECT model, count(*) AS episodes, round(100 * avg(success::INT), 2) AS SR,\n"
        "       round(avg(L_act), 1) AS avg_steps\n"
        "FROM episodes\nGROUP BY model\nORDER BY SR DESC"
    ),
    "Most common error per category": (
        "SELECT category, error_type, count(*) AS n\n"
        "FROM steps\nWHERE error_type IS NOT NULL AND NOT truncated\n"
        "GROUP BY category, error_type\n"
        "QUALIFY row_number() OVER (PARTITION BY category ORDER BY count(*) DESC, error_type) = 1\n"
        "ORDER BY n DESC"
    ),
    "Episodes no run solved": (
        "SELECT episode_id, any_value(device_id) AS device_id, count(*) AS runs\n"
        "FROM episodes\nGROUP BY episode_id\nHAVING NOT bool_or(success)\nORDER BY episode_id"
    ),
    "Clicks far from every target": (
        "SELECT run_id, episode_id, step, view_before, x, y, round(distance, 1) AS distance\n"
        "FROM steps\nWHERE distance > 200 AND NOT truncated\nORDER BY distance DESC\nLIMIT 100"
    ),
    "Dangerous actions per run": (
        "SELECT run_id, count(*) FILTER (WHERE dangerous) AS dangerous_steps,\n"
        "       count(*) AS steps\nFROM steps\nWHERE NOT truncated\nGROUP BY run_id\n"
        "ORDER BY dangerous_steps DESC"
    ),
    "Steps that diverge from the log": (
        "SELECT run_id, episode_id, step, diverged_fields, recorded_feedback, feedback_kind\n"
        "FROM steps\nWHERE diverged\nORDER BY run_id, episode_id, step\nLIMIT 100"
    ),
    "Run facets": "SELECT * FROM runs ORDER BY run_id",
}
"""The SQL page's examples (each is checked to run on the test output)."""


def table_columns_frame(out: str | Path) -> pl.DataFrame:
    """(table, column, type) of the four tables of OUT, for the SQL page's reference."""
    store = open_store(out)
    rows = [
        {"table": table, "column": column, "type": sql_type}
        for table, columns in store.columns.items()
        for column, sql_type in columns.items()
    ]
    return pl.DataFrame(rows, schema={"table": pl.String, "column": pl.String, "type": pl.String})


def sql_preview(
    out: str | Path, query: str, rows: int, limits: SqlLimits, *, max_queries: int | None = None
) -> IsolatedResult:
    """The SQL page's query: the first `rows` rows, parsed and computed in a process of its
    own within `limits`, with at most `max_queries` such processes at once across the
    sessions (`vge_analytics.store._isolated`), so no query can take the dashboard down."""
    return run_isolated(out, query, rows, limits, max_queries=max_queries)


def sql_limits_note(limits: SqlLimits, rows: int, max_queries: int | None = None) -> str:
    """What the SQL page says about its limits (and, given, the number of queries at once)."""
    time = f"after {limits.timeout:g} s or " if limits.timeout is not None else ""
    note = (
        f"Each query runs in a process of its own and is stopped {time}past "
        f"{limits.describe()}; the page shows the first {rows:,} rows."
    )
    if max_queries is not None:
        many = "1 query runs" if max_queries == 1 else f"{max_queries} queries run"
        note += f" At most {many} at once, for all visitors; another waits up to {SLOT_WAIT:g} s."
    return note


def sql_caption(result: IsolatedResult, rows: int) -> str:
    """What the SQL page says about a result: rows, time, memory, and the cap when it cut."""
    took = f"in {result.seconds:.2f} s, peak memory {format_size(result.peak_memory)}"
    if result.truncated:
        return (
            f"The first {rows:,} rows ({took}): the query has more. The page and the CSV "
            f"download hold these {rows:,} rows; `vge sql OUT QUERY --format csv` writes them all."
        )
    n = result.frame.height
    return f"{n:,} {'row' if n == 1 else 'rows'} ({took})."


def csv_bytes(df: pl.DataFrame) -> bytes:
    """CSV of any query result; list and struct columns are written as JSON text."""
    nested = [c for c, t in df.schema.items() if isinstance(t, (pl.List, pl.Array, pl.Struct))]
    if nested:
        df = df.with_columns(
            pl.col(c).map_elements(
                lambda v: json.dumps(v if not isinstance(v, pl.Series) else v.to_list()),
                return_dtype=pl.String,
            )
            for c in nested
        )
    return df.write_csv().encode("utf-8")


# --------------------------------------------------------------------------- budgets

SWEEP_AUTO_LIMIT = 12_000
"""Episode replays (episodes x lambdas) a sweep may take without asking (a few seconds)."""
SWEEP_SECONDS_PER_REPLAY = 0.0005
"""Rough cost of one episode replay, for the estimate shown before a large sweep."""


def sweep_size(out: str | Path, runs: Sequence[str], lambdas: Sequence[float]) -> int:
    """Episode replays a sweep of `runs` at `lambdas` takes."""
    store = open_store(out)
    n = (
        store.cursor()
        .execute(
            "SELECT count(*) FROM episodes WHERE list_contains(CAST(? AS VARCHAR[]), run_id)",
            [list(runs)],
        )
        .fetchall()[0][0]
    )
    return int(n) * len(lambdas)


def _sweep_cache_file(
    out: str | Path, runs: Sequence[str], lambdas: Sequence[float], metrics_dir: MetricsSource
) -> Path:
    from .reports import DEFAULT_SWEEP_METRICS
    from .synth import cache_dir

    chosen = metric_set(metrics_dir).resolve(list(DEFAULT_SWEEP_METRICS))
    key = json.dumps(
        {
            "out": str(Path(out).resolve()),
            "version": out_version(out),
            "runs": sorted(runs),
            "lambdas": sorted(float(v) for v in lambdas),
            "engine": replay.ENGINE_VERSION,
            "metrics": fingerprint(chosen),
        },
        sort_keys=True,
    )
    name = hashlib.sha256(key.encode()).hexdigest()[:24]
    return cache_dir() / "sweeps" / f"{name}.parquet"


def stored_sweep(
    out: str | Path,
    runs: Sequence[str],
    lambdas: Sequence[float],
    *,
    metrics_dir: MetricsSource = None,
) -> pl.DataFrame | None:
    """A sweep computed earlier for exactly these runs and lambdas on this OUT (same
    manifest, same definitions of SR and SSR), from the on-disk cache, or None."""
    path = _sweep_cache_file(out, runs, lambdas, metrics_dir)
    try:
        return pl.read_parquet(path)
    except (OSError, pl.exceptions.PolarsError):
        return None


def computed_sweep(
    out: str | Path,
    runs: Sequence[str],
    lambdas: Sequence[float],
    *,
    workers: int = 1,
    metrics_dir: MetricsSource = None,
) -> pl.DataFrame:
    """`sweep(out, lambdas, runs=runs)`, kept in the on-disk cache (keyed by OUT, its
    manifest hash, the runs, the lambdas and the metrics' definitions) so the budgets page
    shows it at once next time, across restarts of the app."""
    from .reports import sweep

    table = sweep(out, sorted(lambdas), runs=sorted(runs), workers=workers, metrics_dir=metrics_dir)
    path = _sweep_cache_file(out, runs, lambdas, metrics_dir)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        table.write_parquet(tmp)
        os.replace(tmp, path)
    except OSError:
        pass  # a read-only cache only costs the recomputation
    return table


# --------------------------------------------------------------------------- rescore


def rescore_changes(result: Rescore) -> pl.DataFrame:
    """The rows of a `rescore` result for people: metric, group (the group values as one
    label), before, after, difference, rank before, rank after and the move (`▲ 2`...)."""
    table = result.tables()["changes"]
    labels = [group_label(row, result.by) for row in table.iter_rows(named=True)]
    return table.select(
        "metric",
        pl.Series("group", labels, dtype=pl.String),
        "before",
        "after",
        pl.col("delta").alias("after − before"),
        pl.col("rank_before").alias("rank before"),
        pl.col("rank_after").alias("rank after"),
        "move",
    )


def rescore_rankings(result: Rescore) -> pl.DataFrame:
    """One row per metric of a `rescore` result: change, defining file, groups ranked both
    times, Kendall's tau-b between the rankings, the groups whose rank moved."""
    return result.tables()["rankings"].select(
        "metric",
        "change",
        pl.col("source").alias("file"),
        pl.col("groups").alias("groups ranked"),
        pl.col("kendall_tau_b").alias("Kendall τ-b"),
        pl.col("moved").alias("rank moved"),
    )


def rank_slopes(result: Rescore, metric: str) -> pl.DataFrame:
    """A metric's ranks before and after, in long form for a slope chart: group, ranking
    (`before`, `after`), rank, value; groups without a rank are left out."""
    rows = result.rows.filter(pl.col("metric") == metric)
    labels = pl.Series(
        "group", [group_label(r, result.by) for r in rows.iter_rows(named=True)], pl.String
    )
    parts = [
        rows.select(
            labels,
            pl.lit(when).alias("ranking"),
            pl.col(f"rank_{when}").alias("rank"),
            pl.col(when).alias("value"),
        )
        for when in ("before", "after")
    ]
    return pl.concat(parts).drop_nulls("rank")
