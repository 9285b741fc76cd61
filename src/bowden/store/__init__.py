"""The study store: one SQLite file per study, its schema and versions, migrations, encodings, and
the one writer of each table (below runtime, web and study, which all read and write through it)."""
