"""The ``cfm`` command line: one module per command group, shared options in options.py.

:func:`main` (in app.py) builds the parser from the command modules and the ``cfm.commands``
entry points; ``python -m cfm_core.cli`` runs it too.
"""

from .app import main

__all__ = ["main"]
