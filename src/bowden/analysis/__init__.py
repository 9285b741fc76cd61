"""Study analysis: EMG processing with ECG removal, segmentation, and the paper's outcome measures."""
