"""Deprecated alias of :mod:`pushtrain.core.reference` (kept for one release)."""

from pushtrain._compat import alias_module

alias_module(__name__)
