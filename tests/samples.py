"""Protocols the tests share: a short compression run on the built-in simulated rig."""

#: Contact search without confirming approaches, then a ramp and a hold of ``{hold}`` at
#: 100 Hz with a one-term fit: a whole compression run in seconds of virtual time.
SHORT_COMPRESSION = """
[protocol]
name = "short compression"
rig = "compression"

[sample]
name = "the simulated rig's sphere"
diameter = "18.63 mm"

[[step]]
kind = "compression_contact_search"
confirm = 0

[[step]]
kind = "ramp_hold"
hold = "{hold}"
rate = "100 Hz"
terms = 1
"""
