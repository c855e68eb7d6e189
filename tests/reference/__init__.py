"""Readable Python references the compiled engine (``core/csrc``) is held equal to, bit for bit.

They are the formulas the C implements, in the same order, kept here for the tests only: the
product measures and steps with the C. ``chords.py`` is the one reference of vectorised Python
(:func:`pushtrain.planner.passage.chords`), one chord at a time, held equal within 1e-12 m.
"""
