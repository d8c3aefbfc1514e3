"""amb_wavelet."""
