"""The classic fixed-step RK4 on lists of floats: the readable form of the engine's one RK4
(``core/csrc/ode.h`` ``pt_rk4_step``, the same arithmetic in the same order), used by the tests'
reference closed loop (the chain towed by a held robot command) and reference pull guide (the
chain driven backward in time by the last trailer).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

__all__ = ["rk4_step"]


def rk4_step(f: Callable[[float, list], list], t: float, z: Sequence[float], h: float) -> list:
    """One classical Runge-Kutta (RK4) step of ``dz/dt = f(t, z)`` from time ``t`` [s] over ``h``.

    ``z`` is the state as a sequence of floats and ``f(t, z)`` returns its derivative as a list of
    the same length; ``h`` [s] may be negative (integration backward in time). The local error is
    O(h^5); a polynomial right-hand side ``f(t)`` of degree <= 3 is integrated exactly.
    """
    k1 = f(t, z)
    k2 = f(t + 0.5 * h, [a + 0.5 * h * b for a, b in zip(z, k1, strict=True)])
    k3 = f(t + 0.5 * h, [a + 0.5 * h * b for a, b in zip(z, k2, strict=True)])
    k4 = f(t + h, [a + h * b for a, b in zip(z, k3, strict=True)])
    return [a + h / 6.0 * (b1 + 2.0 * b2 + 2.0 * b3 + b4)
            for a, b1, b2, b3, b4 in zip(z, k1, k2, k3, k4, strict=True)]
