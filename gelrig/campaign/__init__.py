"""Campaigns: many simulated runs of a protocol on Dask (issue 18, docs/decisions/0190).

``spec`` reads the campaign file, ``member`` runs one member, ``engine`` runs them on Dask,
``store`` keeps the results as Parquet, ``report`` writes the HTML report.
"""
