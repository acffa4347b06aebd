"""``python -m ami_xr`` is the ``ami-xr`` command."""

from ami_xr.app.cli import run

if __name__ == "__main__":
    run()
