"""Package data of the ground station: the built-in demo scenario."""
