"""A simulated RS30x bus: emulated servos, a paced wire, and scripted hosts (sans-IO apart from port.py)."""

from .bus import SimBus, Transmission
from .scenarios import SCENARIOS, Host, Scenario, run
from .servo import Physics, Servo

__all__ = ["SCENARIOS", "Host", "Physics", "Scenario", "Servo", "SimBus", "Transmission", "run"]
