"""The ``evaluate`` executable's door: :func:`tiago_nav_tools.evaluate.cli.main`."""
from tiago_nav_tools.evaluate.cli import main  # noqa: F401
