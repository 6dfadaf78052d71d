"""What leaves Python for the real-time monitor, and the way back.

Takes an identified model; writes the compact coefficient file rt_monitor loads (coefficients, over the LCM
type of lcm_coefficients) and the monitor's configuration, the robot's bus description compiled (monitor_config,
within the monitor's capacity); plays any run onto the bus through boards (player); reads the monitor's LCM log
(monitor_log, with the lcm-gen types of lcm_messages) and runs the live mission, boards → CAN → rt_monitor →
LCM (mission). Layer: imports everything up to detect and the pipeline.
"""

from .coefficients import read_coefficients, write_coefficients

__all__ = ["read_coefficients", "write_coefficients"]
