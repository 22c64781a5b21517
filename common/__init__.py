"""Utilities every package of the project shares: the user-facing error and atomic
file writing. It imports nothing of the project."""
