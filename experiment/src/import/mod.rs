//! Importers of recordings made on other people's rigs: read into neutral
//! in-memory structures ([`xela_csv`]) and written as sessions ([`xela_session`]).

pub mod xela_csv;
pub mod xela_session;
