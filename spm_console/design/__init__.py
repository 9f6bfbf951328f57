"""Design sweeps: choose the next wrist's geometry (``spm-console design``).

``spec`` reads and bounds a sweep's specification; ``evaluate`` builds and measures one
design (the core's workspace and its figures of merit); ``table`` keeps a sweep's folder
(journal, Parquet table); ``sweep`` runs the designs on Dask; ``ranking`` reads the table
back (best designs, Pareto front, one design's profile). Built from the core and the
profile only.
"""
