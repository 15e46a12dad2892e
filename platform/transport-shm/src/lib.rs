//! Same-host frame transport over iceoryx2 shared memory.
#![warn(missing_docs)]
