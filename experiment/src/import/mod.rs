//! Importers of recordings made on other people's rigs, read into neutral
//! in-memory structures (writing them as sessions is left to the caller).

pub mod xela_csv;
