"""amb_tools."""
