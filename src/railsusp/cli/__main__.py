"""``python -m railsusp.cli``."""

from railsusp.cli import main

main()
