//! FIPA-ACL messages (SC00061) and their string representation (SC00070).
#![warn(missing_docs)]
