"""Altair charts of the dashboard, each a function of a polars DataFrame from the analytics.

Colours follow the paper: error groups blue (grounding), red (execution), green
(navigation); switch classes NP green, PN red; boxes as in the MCAP annotations (targets
green, hits orange, clicks red).

Charts with one series per run (or per group) stay readable at any number of them: a chart
either names every bar on its axis (one bar per group, every label drawn, none cut), or
gives every series a style of its own (`series_styles`: a colour and a point shape, and a
dash for lines; no two series share colour and shape) and lists them all in an untruncated
legend (`series_encoding`). Other pages (and their charts) use the same two functions.
"""

from __future__ import annotations

import base64
from collections.abc import Sequence
from typing import Any, NamedTuple

import altair as alt
import polars as pl

from replay import SCALE
from vge_analytics import ERROR_LABELS, ERROR_TYPES, SWITCH_CLASSES
from vge_analytics.dashboard import ViewPicture

ERROR_COLORS: dict[str, str] = {
    "invalid_coord": "#1f4e9c",
    "component_selection": "#6a9bd8",
    "params_error": "#a61c1c",
    "action_error": "#d9534f",
    "invalid_waiting": "#f2a7a5",
    "switch_view_nn": "#2e7d4f",
    "switch_view_pn": "#8fd19e",
}
"""Per error type: shades of blue (grounding), red (execution), green (navigation)."""

SWITCH_COLORS: dict[str, str] = {"NP": "#2ca02c", "PN": "#d62728", "NN": "#9e9e9e", "PP": "#4c78a8"}
OUTCOME_COLORS: dict[str, str] = {
    "target hit": "#26bf4d",
    "other component": "#ff9900",
    "miss": "#e61a1a",
}
BOX_COLORS: dict[str, str] = {"target": "#26bf4d", "hit": "#ff9900", "component": "#787878"}

# ------------------------------------------------------------------ one series per run

SERIES_COLORS: tuple[str, ...] = (
    "#4e79a7",
    "#f28e2b",
    "#e15759",
    "#76b7b2",
    "#59a14f",
    "#edc948",
    "#b07aa1",
    "#ff9da7",
    "#9c755f",
    "#79706e",
)
"""Ten colours (Tableau 10, darker grey): series k gets colour k mod 10."""
SERIES_SHAPES: tuple[str, ...] = (
    "circle",
    "square",
    "triangle-up",
    "diamond",
    "cross",
    "triangle-down",
    "triangle-right",
    "triangle-left",
)
"""Vega's point shapes: series k gets shape (k div 10) mod 8, so the first 80 series have
80 different (colour, shape) pairs."""
SERIES_DASHES: tuple[tuple[int, ...], ...] = ((), (6, 3), (2, 2), (8, 3, 2, 3), (1, 3), (12, 4))
"""Line dashes: series k gets dash (k div 10) mod 6 (a second cue beside the shape)."""


class SeriesStyle(NamedTuple):
    """How one series (a run, a group) is drawn wherever it is one of several."""

    color: str
    """A `#rrggbb` colour of `SERIES_COLORS`."""
    shape: str
    """A Vega point shape of `SERIES_SHAPES`."""
    dash: tuple[int, ...]
    """A line's stroke dash (`()` solid)."""


def series_styles(names: Sequence[str]) -> dict[str, SeriesStyle]:
    """{name: style} for series in the order given: the k-th distinct name gets colour
    k mod 10 and shape (k div 10) mod 8, so no two of the first 80 share both colour and
    shape (and no two of the first 240 share colour, shape and dash). The same names in the
    same order get the same styles on every page."""
    styles = {}
    for k, name in enumerate(dict.fromkeys(names)):
        band = k // len(SERIES_COLORS)
        styles[name] = SeriesStyle(
            SERIES_COLORS[k % len(SERIES_COLORS)],
            SERIES_SHAPES[band % len(SERIES_SHAPES)],
            SERIES_DASHES[band % len(SERIES_DASHES)],
        )
    return styles


POINT_SIZE = 64
"""Area (px²) of a series' points, in the plot and in the legend alike."""


def full_legend(title: str | None = None, **options: Any) -> alt.Legend:
    """A legend that lists every entry (Vega stops at 30 without `symbolLimit=0`) and cuts
    no label (`labelLimit=0`: no limit)."""
    return alt.Legend(
        title=title,
        symbolLimit=0,
        labelLimit=0,
        labelFontSize=12,
        symbolSize=POINT_SIZE,
        rowPadding=2,
        clipHeight=16,
        **options,
    )


def series_encoding(
    field: str, names: Sequence[str], *, title: str | None = None, line: bool = False
) -> dict[str, Any]:
    """The channels that tell the series of `field` apart (keyword arguments of `encode`):
    colour and shape from `series_styles(names)` (and stroke dash with `line`), each with
    the same domain, so Vega-Lite draws one legend listing every name with its colour and
    shape."""
    styles = series_styles(names)
    domain = list(styles)

    def scale(attr: str) -> alt.Scale:
        return alt.Scale(domain=domain, range=[getattr(s, attr) for s in styles.values()])

    legend = full_legend(title)
    channels: dict[str, Any] = {
        "color": alt.Color(f"{field}:N", sort=domain, scale=scale("color"), legend=legend),
        "shape": alt.Shape(f"{field}:N", sort=domain, scale=scale("shape"), legend=legend),
    }
    if line:
        dashes = alt.Scale(domain=domain, range=[list(s.dash) for s in styles.values()])
        channels["strokeDash"] = alt.StrokeDash(
            f"{field}:N", sort=domain, scale=dashes, legend=legend
        )
    return channels


def legend_height(names: Sequence[str], at_least: int) -> int:
    """Pixel height of a plot whose legend lists `names` one a line beside it: the legend
    fits without being clipped."""
    return max(at_least, 20 * len(dict.fromkeys(names)) + 20)


def label_axis(**options: Any) -> alt.Axis:
    """An axis of names: every label drawn (no overlap removal), none cut."""
    return alt.Axis(labelLimit=0, labelOverlap=False, **options)


PERCENT_FORMAT = ".1f"
"""How shares in percent read in tooltips and labels (58.3, not 58.3333)."""
VALUE_FORMAT = ".2f"
"""How metric values read in tooltips (as in the tables)."""


def _labels() -> list[str]:
    return [ERROR_LABELS[t] for t in ERROR_TYPES]


def _with_type_order(dist: pl.DataFrame) -> pl.DataFrame:
    order = {t: i for i, t in enumerate(ERROR_TYPES)}
    return dist.with_columns(
        type_order=pl.col("error_type").replace_strict(order, return_dtype=pl.Int64)
    )


def _error_color(legend: alt.Legend | None = None) -> alt.Color:
    return alt.Color(
        "label:N",
        title="Error type",
        sort=_labels(),
        scale=alt.Scale(domain=_labels(), range=[ERROR_COLORS[t] for t in ERROR_TYPES]),
        legend=legend if legend is not None else alt.Legend(),
    )


def _bottom_legend(columns: int) -> alt.Legend:
    """A legend under the plot, so stacked-bar charts of one page share their plot width."""
    return alt.Legend(orient="bottom", columns=columns, titleOrient="left")


PAGE_WIDTH = 940
"""Pixels of the main column a chart may take (the wide layout in a 1400 px window)."""


def _label_pixels(names: Sequence[str]) -> int:
    """About how wide the longest of `names` is drawn as an axis label (12 px font)."""
    return 6 * max((len(str(n)) for n in names), default=0) + 12


def metric_bars(long: pl.DataFrame, metric_order: Sequence[str], group_order: Sequence[str]):
    """One small bar chart per metric (columns: group, metric, value, direction): a
    horizontal bar per group in the colours of `series_styles`, the panels in rows that
    share the groups' axis, which names every group at the start of each row (the bars are
    named, so no legend)."""
    groups = list(dict.fromkeys(group_order))
    styles = series_styles(groups)
    plot = 140
    columns = max(1, min(4, (PAGE_WIDTH - _label_pixels(groups)) // (plot + 30)))
    base = (
        alt.Chart(long.to_pandas())
        .mark_bar()
        .encode(
            y=alt.Y("group:N", sort=groups, title=None, axis=label_axis()),
            x=alt.X("value:Q", title=None, axis=alt.Axis(tickCount=4)),
            color=alt.Color(
                "group:N",
                sort=groups,
                scale=alt.Scale(domain=groups, range=[s.color for s in styles.values()]),
                legend=None,
            ),
            tooltip=["group", "metric", alt.Tooltip("value:Q", format=VALUE_FORMAT), "direction"],
        )
        .properties(width=plot, height=alt.Step(14 if len(groups) > 12 else 18))
    )
    return (
        base.facet(
            facet=alt.Facet("metric:N", sort=list(metric_order), title=None), columns=columns
        )
        .resolve_scale(x="independent")
        .configure_header(labelFontSize=13, labelFontWeight="bold")
    )


def error_donut(dist: pl.DataFrame):
    """The paper's error pie (as a donut) for one group (columns: label, count, share)."""
    data = (
        _with_type_order(dist.filter(pl.col("count") > 0))
        .with_columns(percent=pl.format("{}%", pl.col("share").round(1)))
        .to_pandas()
    )
    base = alt.Chart(data).encode(
        theta=alt.Theta("count:Q", stack=True),
        color=_error_color(),
        order=alt.Order("type_order:Q"),
        tooltip=["label", "count", alt.Tooltip("share:Q", format=PERCENT_FORMAT, title="share %")],
    )
    arcs = base.mark_arc(innerRadius=70, outerRadius=140)
    text = base.mark_text(radius=165, size=12).encode(text="percent:N", color=alt.value("#333"))
    return alt.layer(arcs, text).properties(width=360, height=340)


def _group_axis(group_order: Sequence[str]) -> alt.Y:
    """One horizontal bar per group, in the given order, its whole name shown."""
    return alt.Y("group:N", sort=list(group_order), title=None, axis=label_axis())


def _share_x(title: str) -> alt.X:
    """Shares in percent on 0..100 exactly: stacked shares that add up to 100.000001 do not
    stretch the axis to 110."""
    return alt.X("share:Q", title=title, scale=alt.Scale(domain=[0, 100], nice=False, clamp=True))


def _share_axes(group_order: Sequence[str]) -> dict:
    """One horizontal bar per group, its length the share of errors (0..100 %)."""
    return {
        "y": _group_axis(group_order),
        "x": _share_x("share of errors (%)"),
    }


def error_stacked(dist: pl.DataFrame, group_order: Sequence[str]):
    """Stacked bars of error-type shares, one bar per group (columns: group, label, share)."""
    return (
        alt.Chart(_with_type_order(dist).to_pandas(), title="Error types")
        .mark_bar()
        .encode(
            **_share_axes(group_order),
            color=_error_color(_bottom_legend(4)),
            order=alt.Order("type_order:Q"),
            tooltip=["group", "label", "count", alt.Tooltip("share:Q", format=PERCENT_FORMAT)],
        )
        .properties(height=alt.Step(24))
    )


GROUP_COLORS: dict[str, str] = {
    "grounding": "#1f4e9c",
    "execution": "#a61c1c",
    "navigation": "#2e7d4f",
}


def _stacked_shares(
    frame: pl.DataFrame,
    column: str,
    colors: dict[str, str],
    group_order: Sequence[str],
    *,
    label: str,
    x: alt.X,
    title: str | None = None,
    legend: alt.Legend | None = None,
):
    """Bars of shares per group, stacked by `column` in the order (and colours) of `colors`."""
    names = list(colors)
    order = f"{column}_order"
    data = frame.with_columns(
        pl.col(column)
        .replace_strict({c: i for i, c in enumerate(names)}, return_dtype=pl.Int64)
        .alias(order)
    )
    chart = alt.Chart(data.to_pandas(), title=title) if title else alt.Chart(data.to_pandas())
    return (
        chart.mark_bar()
        .encode(
            y=_group_axis(group_order),
            x=x,
            color=alt.Color(
                f"{column}:N",
                title=label,
                sort=names,
                scale=alt.Scale(domain=names, range=[colors[c] for c in names]),
                legend=legend if legend is not None else alt.Undefined,
            ),
            order=alt.Order(f"{order}:Q"),
            tooltip=["group", column, "count", alt.Tooltip("share:Q", format=PERCENT_FORMAT)],
        )
        .properties(height=alt.Step(24))
    )


def error_group_stacked(groups: pl.DataFrame, group_order: Sequence[str]):
    """Stacked bars of error-group shares (grounding, execution, navigation) per group."""
    return _stacked_shares(
        groups,
        "error_group",
        GROUP_COLORS,
        group_order,
        label="Error group",
        x=_share_axes(group_order)["x"],
        title="Error groups",
        legend=_bottom_legend(3),
    )


def switch_stacked(classes: pl.DataFrame, group_order: Sequence[str]):
    """The paper's switch-view figure: NP/PN/NN/PP shares per group, stacked."""
    return _stacked_shares(
        classes,
        "switch_class",
        {c: SWITCH_COLORS[c] for c in SWITCH_CLASSES},
        group_order,
        label="Switch class",
        x=_share_x("share of classified switches (%)"),
    )


def ratio_bars(df: pl.DataFrame, metric: str, group_order: Sequence[str]):
    """Horizontal bars of one metric per group (columns: group, <metric>)."""
    return (
        alt.Chart(df.to_pandas(), title=metric)
        .mark_bar()
        .encode(
            y=_group_axis(group_order),
            x=alt.X(f"{metric}:Q", title=metric),
            tooltip=["group", alt.Tooltip(f"{metric}:Q", format=VALUE_FORMAT)],
        )
        .properties(height=alt.Step(20))
    )


def sweep_lines(gain: pl.DataFrame, y_title: str):
    """The paper's budget figure: SR gain over the baseline lambda, one line per group,
    each with its own colour, point shape and dash (`series_encoding`), all of them in the
    legend."""
    groups = sorted(gain["group"].unique().to_list())
    return (
        alt.Chart(gain.to_pandas())
        .mark_line(point=alt.OverlayMarkDef(filled=True, size=POINT_SIZE))
        .encode(
            x=alt.X("lambda:Q", title="λ (budget redundancy factor)", axis=alt.Axis(tickMinStep=1)),
            y=alt.Y("gain:Q", title=y_title),
            **series_encoding("group", groups, line=True),
            tooltip=[
                "group",
                "lambda",
                alt.Tooltip("SR:Q", format=VALUE_FORMAT),
                alt.Tooltip("gain:Q", format=VALUE_FORMAT),
            ],
        )
        .properties(height=legend_height(groups, 360))
    )


def rank_slopes(slopes: pl.DataFrame, metric: str):
    """A metric's ranks before and after a rescore, one line per group (columns: group,
    ranking, rank, value), each with its own colour, point shape and dash; rank 1 at the
    top, tall enough for the legend of every group."""
    groups = sorted(slopes["group"].unique().to_list())
    return (
        alt.Chart(slopes.to_pandas(), title=f"{metric}: rank before → after")
        .mark_line(point=alt.OverlayMarkDef(filled=True, size=POINT_SIZE))
        .encode(
            x=alt.X("ranking:N", sort=["before", "after"], title=None, axis=alt.Axis(labelAngle=0)),
            y=alt.Y("rank:Q", scale=alt.Scale(reverse=True, zero=False), title="rank (1 = best)"),
            **series_encoding("group", groups, line=True),
            tooltip=["group", "ranking", "rank", alt.Tooltip("value:Q", format=VALUE_FORMAT)],
        )
        # the width is the plot's and the legend's (the page draws the chart as wide as that)
        .properties(height=legend_height(groups, 240), width=360 + _label_pixels(groups) + 40)
    )


def diff_forest(cmp: pl.DataFrame, label_a: str, label_b: str):
    """Per metric, B - A with its 95% bootstrap interval (columns: metric, direction, unit,
    diff, ci_low, ci_high); the dot is green where B is better (by the metric's direction),
    red where it is worse; one panel per unit so percentages and ratios keep their scales."""
    better = pl.when(pl.col("direction") == "higher").then(pl.col("diff") > 0)
    data = (
        cmp.filter(pl.col("diff").is_not_null())
        .with_columns(better=better.otherwise(pl.col("diff") < 0))
        .to_pandas()
    )
    base = alt.Chart(data).encode(
        y=alt.Y("metric:N", sort=list(data["metric"]), title=None),
    )
    bars = base.mark_rule(strokeWidth=2).encode(
        x=alt.X("ci_low:Q", title=f"{label_b} − {label_a} (95% CI)"), x2="ci_high:Q"
    )
    dots = base.mark_point(filled=True, size=70).encode(
        x="diff:Q",
        color=alt.condition(alt.datum.better, alt.value("#2ca02c"), alt.value("#d62728")),
        tooltip=[
            "metric",
            alt.Tooltip("A:Q", format=VALUE_FORMAT, title=label_a),
            alt.Tooltip("B:Q", format=VALUE_FORMAT, title=label_b),
            alt.Tooltip("diff:Q", format=VALUE_FORMAT),
            alt.Tooltip("ci_low:Q", format=VALUE_FORMAT),
            alt.Tooltip("ci_high:Q", format=VALUE_FORMAT),
        ],
    )
    zero = alt.Chart().mark_rule(color="#999", strokeDash=[4, 4]).encode(x=alt.datum(0))
    return (
        alt.layer(bars, dots, zero, data=data)
        .properties(width=260, height=alt.Step(22))
        .facet(row=alt.Row("unit:N", title=None))
        .resolve_scale(x="independent", y="independent")
    )


def side_by_side(cmp: pl.DataFrame, label_a: str, label_b: str):
    """Metric values of the two runs side by side, one small panel per metric."""
    long = cmp.select("metric", "A", "B").unpivot(
        index="metric", on=["A", "B"], variable_name="run", value_name="value"
    )
    long = long.with_columns(
        pl.col("run").replace_strict({"A": label_a, "B": label_b}, return_dtype=pl.String)
    )
    return (
        alt.Chart(long.to_pandas())
        .mark_bar()
        .encode(
            x=alt.X("run:N", sort=[label_a, label_b], title=None, axis=alt.Axis(labels=False)),
            y=alt.Y("value:Q", title=None),
            color=alt.Color(
                "run:N",
                sort=[label_a, label_b],
                scale=alt.Scale(
                    domain=[label_a, label_b],
                    range=[s.color for s in series_styles([label_a, label_b]).values()],
                ),
                legend=full_legend(),
            ),
            tooltip=["metric", "run", alt.Tooltip("value:Q", format=VALUE_FORMAT)],
        )
        .properties(width=90, height=110)
        .facet(facet=alt.Facet("metric:N", sort=list(cmp["metric"]), title=None), columns=6)
        .resolve_scale(y="independent")
    )


def _data_uri(picture: ViewPicture) -> str:
    mime = "image/jpeg" if picture.format in ("jpg", "jpeg") else f"image/{picture.format}"
    return f"data:{mime};base64," + base64.b64encode(picture.data).decode("ascii")


def click_scatter(
    picture: ViewPicture, boxes: pl.DataFrame, points: pl.DataFrame, width: int = 640
):
    """Click points over the device view with the component boxes (targets in green)."""
    height = round(width * picture.height / picture.width)
    x_scale = alt.Scale(domain=[0, SCALE], nice=False, zero=False)
    y_scale = alt.Scale(domain=[SCALE, 0], nice=False, zero=False)
    x_axis = alt.Axis(title=f"x (0..{SCALE})", grid=False)
    y_axis = alt.Axis(title=f"y (0..{SCALE})", grid=False)
    corners = {"x": 0, "x2": SCALE, "y": 0, "y2": SCALE, "url": _data_uri(picture)}
    image = (
        alt.Chart(alt.Data(values=[corners]))
        .mark_image(aspect=False, opacity=0.9)
        .encode(
            x=alt.X("x:Q", scale=x_scale, axis=x_axis),
            x2="x2:Q",
            y=alt.Y("y:Q", scale=y_scale, axis=y_axis),
            y2="y2:Q",
            url="url:N",
        )
    )
    roles = ["target", "component"]
    rects = (
        alt.Chart(boxes.to_pandas())
        .mark_rect(fillOpacity=0, strokeWidth=2)
        .encode(
            x=alt.X("x0:Q", scale=x_scale),
            x2="x1:Q",
            y=alt.Y("y0:Q", scale=y_scale),
            y2="y1:Q",
            stroke=alt.Stroke(
                "role:N",
                title="Box",
                scale=alt.Scale(domain=roles, range=[BOX_COLORS[r] for r in roles]),
            ),
            tooltip=["component", "role"],
        )
    )
    outcomes = list(OUTCOME_COLORS)
    dots = (
        alt.Chart(points.to_pandas())
        .mark_point(filled=True, size=40, opacity=0.75)
        .encode(
            x=alt.X("x:Q", scale=x_scale),
            y=alt.Y("y:Q", scale=y_scale),
            color=alt.Color(
                "outcome:N",
                title="Click",
                scale=alt.Scale(domain=outcomes, range=[OUTCOME_COLORS[o] for o in outcomes]),
            ),
            tooltip=[
                "run_id",
                "episode_id",
                "step",
                "outcome",
                "error_type",
                alt.Tooltip("distance:Q", format=".1f"),
            ],
        )
    )
    return alt.layer(image, rects, dots).properties(width=width, height=height)


def cost_frontier(plane: pl.DataFrame):
    """SR against the cost per episode, one point per run (`dashboard.cost_frontier`): the
    runs on the frontier in green, joined by the staircase no other run gets above-left of."""
    df = plane.to_pandas()
    x = alt.X("cost_per_episode:Q", title="USD per episode", scale=alt.Scale(zero=False))
    y = alt.Y("SR:Q", title="SR (%)", scale=alt.Scale(domain=[0, 100]))
    points = (
        alt.Chart(df)
        .mark_circle(size=90)
        .encode(
            x=x,
            y=y,
            color=alt.Color(
                "frontier:N",
                title="on the frontier",
                scale=alt.Scale(domain=[True, False], range=["#2ca02c", "#9e9e9e"]),
            ),
            tooltip=[
                "run_id",
                alt.Tooltip("SR:Q", format=PERCENT_FORMAT),
                alt.Tooltip("cost_per_episode:Q", format="$.4f", title="USD per episode"),
                "frontier",
            ],
        )
    )
    labels = points.mark_text(align="left", dx=8, dy=-6).encode(text="run_id:N")
    line = (
        alt.Chart(df[df["frontier"]])
        .mark_line(interpolate="step-after", color="#2ca02c", opacity=0.6)
        .encode(x=x, y=y)
    )
    return (line + points + labels).properties(height=320)


def pair_heatmap(matrix: pl.DataFrame, order: Sequence[str], metric: str):
    """Every pair's adjusted p-value as a square (columns: row, column, diff, p_adjusted,
    significant, text): darker where the difference is surer; the cell text is the p-value."""
    data = matrix.to_pandas()
    base = alt.Chart(data).encode(
        x=alt.X("column:N", sort=list(order), title=None),
        y=alt.Y("row:N", sort=list(order), title=None),
    )
    cells = base.mark_rect().encode(
        color=alt.Color(
            "p_adjusted:Q",
            title="adjusted p",
            scale=alt.Scale(type="log", domain=[1e-4, 1], reverse=True, clamp=True),
        ),
        tooltip=[
            "row",
            "column",
            alt.Tooltip("diff:Q", format=".2f", title=f"{metric}: column − row"),
            alt.Tooltip("p_adjusted:Q", format=".4f"),
            "significant",
        ],
    )
    text = base.mark_text(fontSize=10).encode(
        text="text:N",
        color=alt.condition("datum.p_adjusted < 0.01", alt.value("white"), alt.value("black")),
    )
    return alt.layer(cells, text).properties(width=alt.Step(46), height=alt.Step(26))


def passk_lines(curves: pl.DataFrame):
    """pass@k and pass^k against k, one line per group (columns: group, k, measure, value,
    low, high), the band its 95% interval; one panel per measure."""
    base = alt.Chart(curves.to_pandas()).encode(
        x=alt.X("k:Q", title="k (runs drawn)", axis=alt.Axis(tickMinStep=1)),
        color=alt.Color("group:N", title=None),
    )
    band = base.mark_area(opacity=0.15).encode(y=alt.Y("low:Q", title="%"), y2="high:Q")
    line = base.mark_line(point=True).encode(
        y="value:Q",
        tooltip=["group", "measure", "k", alt.Tooltip("value:Q", format=".2f")],
    )
    return (
        alt.layer(band, line)
        .properties(width=320, height=260)
        .facet(column=alt.Column("measure:N", title=None))
    )
