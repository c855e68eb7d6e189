"""The train model and the control law: what the planner and the co-simulation both stand on.

Chain kinematics (:mod:`.kinematics`), line/arc reference paths (:mod:`.reference`), the backward
controller (Kanayama tracking in the travel frame + inverse chain, :mod:`.controller`), the pull
guide (:mod:`.pulling`), one step of the closed loop shared by the co-simulation and the planner's
train check (:mod:`.tracking`), the slip-aware governor (:mod:`.governor`), open-loop command
profiles (:mod:`.openloop`), the closed-form analysis of the law (:mod:`.analysis`, Eq. 9, 12, 13)
and a fixed-step RK4 (:mod:`.ode`).

The same control law in C (``csrc/control.c``, compiled on first use and loaded with ctypes by
:mod:`.native`) backs :class:`.native_controller.NativeController` and
:class:`.native_reference.NativeReference` / :class:`.native_reference.NativeLeader`; tests
hold it equal to the Python modules.

This package imports numpy and scipy only: never the planner, the co-simulation, fmpy or ompl.
"""

__all__: list[str] = []
