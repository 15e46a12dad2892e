//! An error kept as the cause of another error. An error that holds an error of its own type
//! needs it behind a pointer, and one reported more than once needs it cloneable; a plain
//! `Box<E>` or `Arc<E>` would then be the `source()`, a wrapper whose `downcast_ref::<E>()` fails.
//! [`Cause`] is no `std::error::Error` of its own but dereferences to `E` (as `anyhow::Error`
//! does), so a `#[source] field: Cause<E>` under thiserror makes `source()` the `E` itself.
//! It depends on nothing, so every layer may use it.
#![warn(missing_docs)]

use std::fmt;
use std::ops::Deref;
use std::sync::Arc;

/// `E`, shared: cloning it clones a pointer; it compares, prints and dereferences as `E`.
#[derive(Debug, PartialEq, Eq)]
pub struct Cause<E>(Arc<E>);

impl<E> Clone for Cause<E> {
    fn clone(&self) -> Self {
        Self(Arc::clone(&self.0))
    }
}

impl<E> From<E> for Cause<E> {
    fn from(error: E) -> Self {
        Self(Arc::new(error))
    }
}

impl<E> Deref for Cause<E> {
    type Target = E;

    fn deref(&self) -> &E {
        &self.0
    }
}

impl<E: fmt::Display> fmt::Display for Cause<E> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.0.fmt(f)
    }
}
