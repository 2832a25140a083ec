"""mrodrake: LTL planning and adaptive control of multi-robot-object systems (Verginis, Kantaros, Dimarogonas)."""

__version__ = "0.1.0"
