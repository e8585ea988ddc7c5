"""Ready-made benchmark problems of the paper."""
