"""Ground control: links to vehicles, the mission protocol, monitoring, re-tasking, CLI."""

__version__ = "0.1.0"
