"""``python -m pickplan.cli``: the ``pickplan`` command (the Makefile's entry point)."""

from pickplan.cli.main import main

raise SystemExit(main())
