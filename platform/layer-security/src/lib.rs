//! Security layer: Ed25519 identities, X25519 agreement, AES-256-GCM, pre-shared keys.
#![warn(missing_docs)]
