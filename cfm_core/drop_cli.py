"""``cfm drop-test``: placeholder until the solver lands (filled in by the drop-test work)."""

COMMANDS: dict = {}


def add_parser(sub) -> None:
    return None
