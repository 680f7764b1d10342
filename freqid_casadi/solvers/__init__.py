"""Stage solvers (layer L3): IPOPT through CasADi, and the thesis's barrier + LM."""

from .common import StageResult, Status, TERMINATION_MESSAGES, find_active_constraints

__all__ = ["StageResult", "Status", "TERMINATION_MESSAGES", "find_active_constraints"]
