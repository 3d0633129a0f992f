"""The engine version written into every manifest."""

ENGINE_VERSION = "0.2.0"
"""Changes whenever replay output for the same inputs may change (invalidates caches)."""
