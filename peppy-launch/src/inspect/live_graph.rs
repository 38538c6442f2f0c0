//! `graph --live`: the running stack as it is.
