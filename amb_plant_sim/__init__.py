"""amb_plant_sim."""
