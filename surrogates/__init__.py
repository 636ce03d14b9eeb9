"""surrogates: designs of experiments and Gaussian-process surrogates (knows nothing about beams)."""
