"""Where the tests find the project and their data, wherever a test module lies."""

from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
"""The project's root (profiles/, the package)."""
TESTS = ROOT / "tests"
"""The tests' folder (data/, the console's snapshots)."""
