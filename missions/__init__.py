"""A `Plan` becomes MAVLink mission items and the files people exchange."""
