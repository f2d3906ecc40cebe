"""Running scenes end to end: scene -> model -> backend -> result -> post-processing, with outcome
objects that hold the histories, tabulate them and write the same files as the command line."""

from .pipeline import DropTestOutcome, ReactionOutcome, default_backend, drop_test, reaction_test, run_model

__all__ = ["DropTestOutcome", "ReactionOutcome", "default_backend", "drop_test", "reaction_test", "run_model"]
