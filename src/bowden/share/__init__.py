"""Sharing a study: the store as a BIDS dataset (:mod:`bowden.share.bids`) and the statistics as an
R script beside the exported long table (:mod:`bowden.share.r_script`)."""
