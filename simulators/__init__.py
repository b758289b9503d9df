"""Simulators of the instruments, speaking their wire protocols, driven by the contact physics."""
