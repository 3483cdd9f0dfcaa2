//! Image quality at equal time: tree-ID colours (the forest tool's `--id-colors`) and
//! what the quality example measures with them.

/// Distinct values per colour channel: 64³ − 1 trees can be told apart.
const LEVELS: u32 = 64;
/// Bytes between two levels: a rounding of ±1 in the colour's conversion still decodes.
const STEP: u32 = 256 / LEVELS;

/// The sRGB colour of instance `index` (black is no tree).
pub fn id_color(index: u32) -> [u8; 3] {
    let id = index + 1;
    let channel = |shift: u32| (((id >> shift) % LEVELS) * STEP + STEP / 2) as u8;
    [channel(12), channel(6), channel(0)]
}

/// The instance whose [`id_color`] is `rgb`, within a rounding; `None` for black.
pub fn decode(rgb: [u8; 3]) -> Option<u32> {
    let level = |byte: u8| (u32::from(byte) / STEP).min(LEVELS - 1);
    let id = (level(rgb[0]) << 12) | (level(rgb[1]) << 6) | level(rgb[2]);
    id.checked_sub(1)
}

/// The linear colour that an sRGB render target stores as `rgb`.
pub fn linear(rgb: [u8; 3]) -> [f32; 3] {
    rgb.map(|byte| {
        let c = f32::from(byte) / 255.0;
        if c <= 0.04045 {
            c / 12.92
        } else {
            ((c + 0.055) / 1.055).powf(2.4)
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_id_decodes_through_a_rounding() {
        for index in (0..200_000).step_by(7) {
            let rgb = id_color(index);
            for delta in [-1i16, 0, 1] {
                let off = rgb.map(|b| (i16::from(b) + delta).clamp(0, 255) as u8);
                assert_eq!(decode(off), Some(index), "{index} {rgb:?} {delta}");
            }
        }
        assert_eq!(decode([0, 0, 0]), None);
    }
}
