"""`python -m vge_analytics.commands._serve <streamlit run arguments>`: Streamlit, warmed up first.

`vge app` starts the dashboard through this module rather than `python -m streamlit`: before
the server listens it imports the heavy libraries and opens the replay output (its tables,
Parquet footers, within the pages' query bounds, so the pages find the same store) and runs
the leaderboard's default query, and hashes the manifest and the code (the keys of the pages'
cached results), all in the server process, so the first page a person opens does not pay for
them (they are most of a cold first load); what it made is then frozen out of the garbage
collector's work. It also starts the forkserver the SQL page's query processes come from,
and the first of them: the SQL page's standby, which opens OUT and waits for the page's first
query (`vge_analytics.store._standby`).
"""

from __future__ import annotations

import gc
import os
import sys

import app
from vge_analytics.dashboard import OUT_ENV


def _warm(out: str) -> None:
    from vge_analytics.dashboard import out_version
    from vge_analytics.store import code_key, warm_query_processes

    # The SQL page's query processes fork from a forkserver that has the libraries loaded;
    # the first, the standby (forked by `app.warm`), opens OUT while this process warms up,
    # not while the first page loads (on two cores that slowed the Leaderboard's first
    # visit by seconds at 100x).
    warm_query_processes()
    # The dashboard's modules (the page scripts import the same module objects), and OUT
    # opened as the pages open it.
    app.warm(out)
    # What every page's first data call asks for: the manifest's hash (the in-process key,
    # 0.3-0.5 s for a large manifest) and the code's (the key of the results kept on disk).
    out_version(out)
    code_key()
    # What the warm-up made (the modules, OUT's store) lives as long as the server: frozen, it
    # is left out of every later collection, among them the full one Streamlit runs after
    # each script run (0.1 to 0.4 s of the first page's visit at 100x).
    gc.collect()
    gc.freeze()


def main() -> int:
    out = os.environ.get(OUT_ENV)
    if out:
        _warm(out)
    from streamlit.web import cli

    sys.argv = ["streamlit", *sys.argv[1:]]
    return cli.main()


if __name__ == "__main__":
    sys.exit(main())
