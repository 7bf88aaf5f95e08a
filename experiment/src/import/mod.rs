//! Importers of recordings made on other people's rigs: read into neutral
//! in-memory structures ([`xela_csv`] for xela-imanlab, [`xela_psc`] for
//! xela-psc) and written as sessions ([`xela_session`],
//! [`xela_psc_session`]), with the parts they share ([`robot_state`] and a
//! few private helpers).

mod csv_parse;
pub mod robot_state;
mod session_parts;
pub mod xela_csv;
pub mod xela_psc;
pub mod xela_psc_session;
pub mod xela_session;
