"""The sensorless controller: assistance → compensation → limits, one pure ``step()`` per cycle."""

from bowden.control.command import Command
from bowden.control.controller import Controller, build_controller
from bowden.control.faults import Fault, Limit
from bowden.control.limits import ControllerLimits

__all__ = ["Command", "Controller", "ControllerLimits", "Fault", "Limit", "build_controller"]
