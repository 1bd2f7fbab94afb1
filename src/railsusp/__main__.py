"""``python -m railsusp``: the ``railsusp`` command (:func:`railsusp.command.main`), for an
environment whose scripts folder is not on the PATH."""

from railsusp.command import main

main()
