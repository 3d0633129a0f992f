"""The fast path: whole batches of episodes replayed to Arrow tables, proven identical to the reference."""
