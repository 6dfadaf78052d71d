"""dynid: identification of robot dynamics (inertia, F/T offsets, friction, motor gains) in one regression."""

__version__ = "0.1.0"
