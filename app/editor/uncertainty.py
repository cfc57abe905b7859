"""``scribble_classes`` for ``app.editor.classify_job``, which imports it from here.

The uncertainty model moved to :mod:`core.edit.uncertainty` (no Qt); the view
is :mod:`app.editor.uncertainty_view`. This module goes when classify_job is
replaced by the core conversion step.
"""

from core.edit.uncertainty import scribble_classes

__all__ = ["scribble_classes"]
