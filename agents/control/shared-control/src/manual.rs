//! The manual paradigm: the user's command goes to the wheels untouched.

use crate::{ControlError, Intervention, SharedController, SharedInput, SharedOutput};

/// No assistance; the reference the shared controllers are compared against.
#[derive(Debug, Clone, Copy, Default)]
pub struct Manual;

impl SharedController for Manual {
    fn step(&mut self, input: &SharedInput<'_>) -> Result<SharedOutput, ControlError> {
        let command = input.user.validate()?;
        Ok(SharedOutput {
            command,
            intervention: Intervention::default(),
        })
    }
}
