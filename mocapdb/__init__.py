"""mocapdb: annotate and retrieve motion capture data with SQL.

Implements Müller, Baak & Seidel, "Efficient and Robust Annotation of Motion
Capture Data" (SCA 2009) on DuckDB.
"""
__version__ = "0.1.0"
