"""Drivers for the real instruments; each speaks its instrument's wire protocol."""
