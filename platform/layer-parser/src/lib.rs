//! Parser layer: well-formed FIPA-ACL from registered senders only.
#![warn(missing_docs)]
