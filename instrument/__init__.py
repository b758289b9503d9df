"""The core of gelrig: clock, units, contact physics, analysis and the instrument contracts.

Nothing here imports drivers, simulators or the GUI (see docs/decisions/0001-layout.md).
"""
