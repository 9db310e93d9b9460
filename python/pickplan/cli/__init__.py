"""The ``pickplan`` command: one module per command group (``main`` wires them).""" 
from pickplan.cli.main import main

__all__ = ["main"]
