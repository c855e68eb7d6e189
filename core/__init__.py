"""The train model and the control law: what the planner and the co-simulation both stand on.

Chain kinematics (:mod:`.kinematics`; the bodies' positions from the headings are the engine's C,
``pt_chain_positions``), line/arc reference paths (:mod:`.segment`, :mod:`.reference`; given as
samples: :mod:`.sampled_reference`), the backward
controller (Kanayama tracking in the travel frame + inverse chain, :mod:`.controller`), the pull
guide (:mod:`.pulling`), one control instant (:mod:`.tracking`), the slip-aware governor
(:mod:`.governor`), open-loop command profiles (:mod:`.openloop`), the closed-form analysis of
the law (:mod:`.analysis`, Eq. 9, 12, 13).

The control law, the reference, the pull guide and the sensor model are computed in C
(``csrc/``, compiled on first use and loaded with ctypes by :mod:`.native`), each with one
Python face: :class:`.controller.Controller`, :class:`.reference.Reference`,
:class:`.pulling.PullGuide`; the readable Python versions the C is held equal to live in the
tests (``tests/reference/``). With the chain integration and checks (``csrc/rollout.c``) it is
the one closed-loop engine: the planner's search and final check run it through :mod:`.engine`,
the co-simulation master's step loop and the controller FMU call its C directly.

This package imports numpy and scipy only: never the planner, the co-simulation, fmpy or ompl.
"""

__all__: list[str] = []
