"""Storage: the DuckDB schema, ingest, stored models, the keyframe index tables, Parquet.

Everything that reads or writes the database lives here; the algorithm
sub-packages below work on arrays only.
"""
