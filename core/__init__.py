"""The train model and the control law: what the planner and the co-simulation both stand on.

Chain kinematics (:mod:`.kinematics`), line/arc reference paths (:mod:`.reference`), the backward
controller (Kanayama tracking in the travel frame + inverse chain, :mod:`.controller`), the pull
guide (:mod:`.pulling`), one control instant (:mod:`.tracking`), the slip-aware governor
(:mod:`.governor`), open-loop command profiles (:mod:`.openloop`), the closed-form analysis of
the law (:mod:`.analysis`, Eq. 9, 12, 13) and a fixed-step RK4 (:mod:`.ode`).

The same control law in C (``csrc/control.c``, compiled on first use and loaded with ctypes by
:mod:`.native`) backs :class:`.native_controller.NativeController` and
:class:`.native_reference.NativeReference` / :class:`.native_reference.NativeLeader`; tests
hold it equal to the Python modules. With the sensor model (``csrc/sensors.c``) and the chain
integration and checks (``csrc/rollout.c``) it is the one closed-loop engine: the planner's
search and final check run it through :mod:`.engine`, the co-simulation master's step loop
and the controller FMU call its C directly.

This package imports numpy and scipy only: never the planner, the co-simulation, fmpy or ompl.
"""

__all__: list[str] = []
