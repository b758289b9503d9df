"""Formatting of analysis results: the HTML report, its tables and PNG figures (matplotlib's
object API on the Agg canvas). Numbers arrive in SI.
"""
