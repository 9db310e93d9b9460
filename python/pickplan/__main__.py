"""``python -m pickplan``: the ``pickplan`` command."""

from pickplan.cli.main import main

raise SystemExit(main())
