"""Studies built on the package's public API, like scipy's benchmarks (layer L7).

Each study is an experiment module returning result dataclasses and a ``*_report`` module
that renders them (Markdown, JSON, figures through :mod:`freqid_casadi.plots`) into a
report folder: ``reproduce`` / ``reproduce_report`` (the thesis's chapter 4), ``ablation`` /
``ablation_report`` (IPOPT vs the barrier-LM, IPOPT's options one at a time), ``noisy`` /
``noisy_report`` (example A on noisy data: the safeguard, the damping floor, weights),
``robot_arm`` / ``robot_arm_report`` (the DaISy robot arm: orders, choice, weight),
``measured`` / ``measured_report`` (the actuator from raw records and the robot arm beside
the outside peers) and ``thesis_matlab`` (the thesis's Appendix A transcribed).
"""

__all__ = []
