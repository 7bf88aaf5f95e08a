//! Sessions: one trial recorded to one MCAP file, and reading it back.
