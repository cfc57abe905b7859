"""The undo history of an edit document: steps of changes, groups, the saved mark.

One history for every kind of change, so Undo takes back the user's last action
whatever it touched; :meth:`History.group` merges what is recorded inside it into one
step (napari's ``block_history``). It keeps the books; the document applies changes.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass

from terratheme.core.edit.changes import Change
from terratheme.core.errors import TerrathemeError


@dataclass(frozen=True, eq=False)
class Step:
    """One undo step: changes applied in order, reverted in reverse order."""

    label: str
    changes: tuple[Change, ...]

    @property
    def nbytes(self) -> int:
        """Memory of the arrays the step keeps alive (an upper bound)."""
        return sum(c.nbytes for c in self.changes)


class History:
    """Undo and redo stacks of :class:`Step`, with grouping and a saved mark."""

    def __init__(self) -> None:
        self._undo: list[Step] = []
        self._redo: list[Step] = []
        self._group: list[Change] | None = None
        self._group_label = ""
        #: ``len(self._undo)`` when the document was last saved; None once unreachable
        self._saved_at: int | None = 0

    # -- recording -------------------------------------------------------------
    def record(self, label: str, changes: Sequence[Change]) -> Step | None:
        """Put already-applied ``changes`` on the history as one step (or into the open group).

        Clears the redo stack. Returns the step, None when ``changes`` is
        empty or a group is open (the group's step is made when it closes).
        """
        if not changes:
            return None
        if self._group is not None:
            self._group.extend(changes)
            return None
        if self._saved_at is not None and self._saved_at > len(self._undo):
            # The saved state was on the redo stack: it can never come back.
            self._saved_at = None
        self._redo.clear()
        step = Step(label, tuple(changes))
        self._undo.append(step)
        return step

    @contextmanager
    def group(self, label: str) -> Iterator[None]:
        """Everything recorded inside the ``with`` block becomes one step called ``label``.

        Nested groups join the outermost. The step is recorded even when the
        block raises, so the history always matches what was applied.
        """
        if self._group is not None:
            yield
            return
        self._group, self._group_label = [], label
        try:
            yield
        finally:
            changes, self._group = self._group, None
            self.record(self._group_label, changes)

    # -- moving ----------------------------------------------------------------
    def pop_undo(self) -> Step | None:
        """The step to revert now (moved to the redo stack), or None."""
        return self._move("undo", self._undo, self._redo)

    def pop_redo(self) -> Step | None:
        """The step to apply again now (moved back to the undo stack), or None."""
        return self._move("redo", self._redo, self._undo)

    def _move(self, what: str, source: list[Step], target: list[Step]) -> Step | None:
        """The last step of ``source`` moved onto ``target`` (None when ``source`` is empty)."""
        self._check_not_grouping(what)
        if not source:
            return None
        step = source.pop()
        target.append(step)
        return step

    def _check_not_grouping(self, what: str) -> None:
        if self._group is not None:
            raise TerrathemeError(f"cannot {what} while the step {self._group_label!r} is open")

    # -- state -----------------------------------------------------------------
    @property
    def undo_steps(self) -> tuple[Step, ...]:
        """Steps that can be undone, oldest first."""
        return tuple(self._undo)

    @property
    def can_undo(self) -> bool:
        return bool(self._undo)

    @property
    def undo_label(self) -> str | None:
        return self._undo[-1].label if self._undo else None

    @property
    def redo_label(self) -> str | None:
        return self._redo[-1].label if self._redo else None

    @property
    def clean(self) -> bool:
        """Whether the document is in the state it was last saved (or opened) in."""
        return self._saved_at == len(self._undo)

    def mark_saved(self) -> None:
        """The document was just saved: this is the clean state now."""
        self._saved_at = len(self._undo)

    @property
    def nbytes(self) -> int:
        """Memory held by the undo and redo stacks."""
        return sum(s.nbytes for s in self._undo) + sum(s.nbytes for s in self._redo)
