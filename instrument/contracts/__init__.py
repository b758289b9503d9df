"""The instrument contracts (``typing.Protocol``) and their configuration tables: stage,
force sensor (DAQ and load-cell chain), rheometer, and the stop-first fault path of drivers.
"""
