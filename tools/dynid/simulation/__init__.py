"""The simulated plant: experiments of a configured arm with known truth, contacts and hidden effects.

Data path: true_robot (the arm) → plant (rigid bodies) + actuation (motors, friction) → controller (reaching
under joint impedance) → experiment (the closed loop) → sensors (what the boards record) → output (files).
Layer: beside robot; imports config, io and robot, and nothing above them imports it but the cli and api.
"""

from .effects import CATALOG, Effect, parse_effect
from .experiment import KINDS, Simulation, SimulationSettings, simulate

__all__ = ["CATALOG", "KINDS", "Effect", "Simulation", "SimulationSettings", "parse_effect", "simulate"]
