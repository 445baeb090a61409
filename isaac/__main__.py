"""`python -m isaac ...`: the `isaac` command, for a Python whose scripts folder is not on PATH."""
from isaac.cli import entry

if __name__ == "__main__":  # pragma: no cover (run as a program)
    entry()
