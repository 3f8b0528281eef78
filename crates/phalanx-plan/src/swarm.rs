//! SWARM-MAPF; written by the swarm owner.
