"""Errors that reach the user as one clear line: bad input (exit status 2) and a
dask cluster that failed a plan (exit status 1)."""


class InputError(Exception):
    """Bad input: names the file (or option) and what is wrong with it.

    ``str(err)`` is the one-line message the CLI prints, e.g.
    ``dem.tif: raster has no CRS``.
    """

    def __init__(self, source, problem: str):
        self.source = str(source) if source is not None else None
        self.problem = problem
        super().__init__(f"{self.source}: {problem}" if self.source else problem)


class ClusterError(Exception):
    """The dask cluster a plan ran on failed it (a worker died, the data it held with
    it): not the input's fault. ``str(err)`` is the one-line message."""
