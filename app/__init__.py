"""The Streamlit dashboard (`vge app`): routing in `streamlit_app.py`, one thin page per file
in `views/`, shared plumbing in `_ui.py`, charts in `_charts.py`.

The page directory is deliberately not called `pages/`: Streamlit treats a `pages/` folder
next to the entry file as an old-style multipage app until some session has called
`st.navigation`, so a deep link such as `/episode_viewer?run=...` opened first on a fresh
server would run the page without the entry file (no sidebar, no facet filters).
"""
