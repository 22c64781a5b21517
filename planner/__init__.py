"""Pure computation: terrain in, hidden reduced-time coverage routes out."""
