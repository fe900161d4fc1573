"""Speed-independent excitations of the gear models: periodic tables, angle map, events."""
