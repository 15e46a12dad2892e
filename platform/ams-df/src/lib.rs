//! FIPA Agent Management System and Directory Facilitator.
#![warn(missing_docs)]
