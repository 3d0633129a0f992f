"""Input and output: loading benchmarks and logs, batches, Parquet parts, manifest, quarantine, MCAP, the runner."""
