"""Teaching Studio: teach a Baxter robot a trajectory skill in the browser."""

__version__ = "0.2.1"
