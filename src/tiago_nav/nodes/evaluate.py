"""The ``evaluate`` executable's door: :func:`tiago_nav.evaluate.cli.main`."""
from tiago_nav.evaluate.cli import main  # noqa: F401
