"""The study: the store, the pipelines that wire everything together, and the report."""
