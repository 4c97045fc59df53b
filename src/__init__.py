"""simgap: how far simulated camera + ArUco pose readings are from hardware, where, and why."""

__version__ = "0.1.0"
