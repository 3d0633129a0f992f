"""SQL: read-only queries over the tables steps, episodes, goals and runs."""

import functools

import streamlit as st

from app import _data as data
from app import _lifecycle as page
from app import _pickers as pickers
from app import _settings as settings
from vge_analytics import AnalyticsError
from vge_analytics import dashboard as dash

limits, max_rows = settings.sql_settings()
max_queries = settings.sql_max_queries()
st.title("SQL")
st.caption(
    "DuckDB SQL over the replay tables `steps`, `episodes`, `goals` and `runs` (one statement, "
    "read-only; no file can be read or written). "
    + dash.sql_limits_note(limits, max_rows, max_queries)
    + " Ctrl+Enter runs the query."
)
examples = dash.EXAMPLE_QUERIES
st.selectbox(
    "Examples",
    list(examples),
    index=None,
    placeholder="Pick an example query",
    key="sql_example",
    on_change=pickers.load_example,
)
pickers.init_state("sql_query", next(iter(examples.values())))
query = st.text_area("Query", height=160, key="sql_query")
with st.expander("Columns of the tables"):
    st.dataframe(data.table_columns(), hide_index=True)
if query.strip():
    try:
        example = next((name for name, text in examples.items() if text == query), None)
        if example is not None:  # kept beside OUT for the next server
            result = data.example_preview(example, max_rows, limits, max_queries=max_queries)
        else:
            result = data.sql_preview(query, max_rows, limits, max_queries=max_queries)
    except AnalyticsError as exc:
        page.show_error(exc)
        page.stop()
    st.caption(dash.sql_caption(result, max_rows))
    st.dataframe(result.frame, hide_index=True)
    st.download_button(
        "Download CSV",
        functools.partial(dash.csv_bytes, result.frame),  # made when clicked, not at each run
        file_name="query.csv",
        mime="text/csv",
        on_click="ignore",
    )
