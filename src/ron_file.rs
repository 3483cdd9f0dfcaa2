//! What every file format of the crate shares: how RON is read, the read → UTF-8 step
//! of every text loader, and the error for a value out of its range.

use bevy::asset::io::Reader;

/// How every RON file of the crate is read: optional fields may be written bare
/// (`knots_x: [...]`) or as `Some(...)`.
pub(crate) fn ron_options() -> ron::Options {
    ron::Options::default().with_default_extension(ron::extensions::Extensions::IMPLICIT_SOME)
}

/// Reads a whole asset as UTF-8 text, with the format's own error for either failure.
pub(crate) async fn read_text<E>(reader: &mut dyn Reader) -> Result<String, E>
where
    E: From<std::io::Error> + From<core::str::Utf8Error>,
{
    let mut bytes = Vec::new();
    reader.read_to_end(&mut bytes).await?;
    match String::from_utf8(bytes) {
        Ok(text) => Ok(text),
        Err(error) => Err(error.utf8_error().into()),
    }
}

/// A value of a file that is out of its range or refers to nothing: which field, and what
/// is wrong with it. Every RON format reports it the same way.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{field}: {message}")]
pub struct FieldError {
    /// The field, as a path into the file (`species[1].scale`, `springs[2].damping`).
    pub field: String,
    /// What is wrong with it.
    pub message: String,
}

/// A [`FieldError`] as the format's own error.
pub(crate) fn invalid<E: From<FieldError>>(field: String, message: impl Into<String>) -> E {
    FieldError {
        field,
        message: message.into(),
    }
    .into()
}
