"""The closed loop, declared once: its participants, the co-simulation that ticks them, the limits that end it."""
