"""amb_controller."""
