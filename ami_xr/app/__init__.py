"""The application layer: the ``ami-xr`` command line, batch runs, the demo and the HTML report.

Everything here is written against the public functions of the layers below (:mod:`ami_xr.io`,
:mod:`ami_xr.dsp`, :mod:`ami_xr.ami`, :mod:`ami_xr.plot`); nothing below imports this package.
"""
