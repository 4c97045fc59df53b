"""Core: configuration parsing, transforms, the rig model, atomic writes and paths (no renderer)."""
