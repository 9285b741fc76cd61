"""sEMG for the study: files imported into a store's trials (EDF, BDF, XDF, CSV) and what the store holds
of them (imports, sync events)."""
