"""Pickers and run facets that together select nothing: the page says so in one line
(`store.check_selection`, the same line as the command line's) instead of an empty table."""

from __future__ import annotations

from .test_pages import open_page, rerun


def warnings(at) -> list[str]:
    return [w.value for w in at.warning]


def test_a_selection_of_no_row_says_so_instead_of_an_empty_table(app_env):
    at = open_page()
    at.sidebar.multiselect[0].select("3")  # history_length: sim-vlm-f-hist3 only
    at.multiselect[0].select("sim-vlm-a")  # Runs
    rerun(at)
    assert warnings(at) == [
        "The selection (meta_history_length = 3, run_id = sim-vlm-a) selects no row: each "
        "value is there, but no row has them all"
    ]
    assert not at.dataframe  # no empty table
    # The same on a page that filters runs only by their facets.
    at = open_page("budgets")
    at.sidebar.multiselect[0].select("3")
    at.sidebar.multiselect[-1].select("sim-vlm-a")  # profile
    rerun(at)
    shown = warnings(at)
    assert len(shown) == 1 and shown[0].endswith(
        "selects no row: each value is there, but no row has them all"
    )
    assert not at.dataframe and not at.get("vega_lite_chart")


def test_a_selection_with_rows_shows_no_warning(app_env):
    at = open_page()
    at.sidebar.multiselect[0].select("3")
    at.multiselect[0].select("sim-vlm-f-hist3")
    rerun(at)
    assert not warnings(at)
    assert list(at.dataframe[0].value["group"]) == ["sim-vlm-f-hist3"]
