"""Old name of :mod:`ami_xr.provenance`, kept while callers switch; import from there."""

from ami_xr.provenance import add_history, history

__all__ = ["add_history", "history"]
