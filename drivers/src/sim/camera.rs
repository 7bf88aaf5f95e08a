//! The simulated camera: renders the ArUco marker on the object.
