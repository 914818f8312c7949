"""The paper: its cases, its figures drawn again, and the evidence for its phase convention.

Imports every layer below it; nothing in :mod:`rattle_core` imports it.
"""
