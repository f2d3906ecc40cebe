"""Material plugins shipped with the project (import name ``cfm_plugins``).

Each module declares energy terms and material specs; they are registered through the
``cfm.materials`` and ``cfm.terms`` entry-point groups in pyproject.toml, exactly as a third-party
plugin would be.
"""
