"""The version of microsim, recorded in every table and batch state it writes."""

__version__ = "0.1.0"
