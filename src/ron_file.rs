//! What every file format of the crate shares: how RON is read, and the read → UTF-8
//! step of every text loader.

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
