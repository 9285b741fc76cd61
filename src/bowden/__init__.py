"""bowden: sensorless tension control of cable-driven exosuits.

Identify a suit's Bowden transmission from bench data, control cable tension without a load cell,
run the controller on real or simulated hardware, and analyse a study end to end.
"""

__version__ = "0.1.0"

__all__ = ["__version__"]
