"""amb_fault_monitor."""
