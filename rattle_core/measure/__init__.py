"""Measured signals: reading a measurement file, and the order analysis of a shaft's speed.

Signal processing of the user's data, below the model (which takes the order maps as inputs)
and importing nothing from the other layers; no plotting.
"""
