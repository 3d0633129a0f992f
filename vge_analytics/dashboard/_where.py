"""Where the dashboard finds OUT: two names the `vge app` and `vge play` commands declare
their options with, kept apart from the modules that read OUT so that `vge --help` imports
none of the table libraries."""

DEFAULT_OUT = "logs-replayed"
"""Where `vge demo` writes the replayed bundled sample; `vge app` opens it by default."""
OUT_ENV = "VGE_APP_OUT"
"""Environment variable naming OUT for the app (set by `vge app`; `--out` wins)."""
