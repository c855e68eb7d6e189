"""Fixed-step integration of small ODE systems held as lists of floats (for per-step loops).

Used by the pull guide (the chain driven backward in time by the last trailer) and by the tests'
reference closed loop (the chain towed by a held robot command; the engine in ``core/csrc``
integrates the same RK4 in C). Plain floats: a numpy call per
stage would cost more than the arithmetic of a few-trailer chain.
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
