"""The ``pickplan`` command: one module per command group; ``pickplan.cli.main`` wires them."""
