"""Bring-up at the real rig (issue 30): guided routines that confirm the instrument facts
gelrig only believes, and write them with their provenance into a confirmed rig file.

``operator`` (who answers: a person or the twin), ``stage`` / ``loadcell`` / ``rheometer``
(each instrument's routines), ``confirmed_file`` (writing the values into the user's rig
file), ``runner`` (one bring-up from start to end). ``gelrig bringup`` is its command.
"""
