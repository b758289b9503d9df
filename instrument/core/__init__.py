"""The core: the injected clock, units, errors, typed configuration fields, identities,
robust noise and binning, and the crash-safe data store. Imports nothing else of gelrig.
"""
