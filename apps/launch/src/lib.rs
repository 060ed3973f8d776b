//! `stride`, the launcher and the operator's commands, as a library: launch profiles
//! ([`profile`]), the supervision of one host's apps ([`supervise`]) and the commands
//! ([`app`]) with the walk's judge ([`walk`]).

pub mod app;
pub mod profile;
pub mod supervise;
pub mod walk;
