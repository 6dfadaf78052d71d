"""Data in and out: recorded experiments as one `Dataset`.

Takes a CSV (csv_format), a candump log of the robot's bus (candump, decoded by cantools with the messages
can_database builds from the configuration's bus description) or
the project's dataset file (dataset), as the robot configuration describes them (load.load_data); estimates
q̇, q̈ from q with the offline, non-causal estimators where they were not recorded (derivatives). Hands on a
`Dataset`; writes datasets, CSVs and candump logs back. Layer: imports config only.
"""

from .dataset import Dataset
from .load import load_data

__all__ = ["Dataset", "load_data"]
