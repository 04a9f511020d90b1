//! Simulation parser (TOSM -> world, SDF/URDF) and the headless simulator; no IO.
