"""The Helmholtz solve's start, now the model's: ``model.guess_history`` (issue 100; these names kept here)."""

from ..model.guess_history import GuessHistory, HistoryWork

__all__ = ["GuessHistory", "HistoryWork"]
