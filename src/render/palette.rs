//! Colours of the class map.
//!
//! Periods are grouped in families (1, 2, 3, 4, 5-8, 9-16, 17-64). The four single periods take
//! Okabe-Ito colours (distinguishable with the common colour-vision deficiencies); each larger
//! family has one hue with lightness steps inside it (designed in CIE LCh, so that the steps are
//! perceptual): 5-8 violet, 9-16 olive to pale yellow, 17-64 browns. The other classes are
//! achromatic (chaotic near-black, aperiodic grey, no impact near-white) or hues no period family
//! uses (quasi-periodic light green, coexisting attractors cyan, unresolved pale pink, failed
//! magenta).
//!
//! Measured with CIE76 (tested in `tests/figures.rs`): two colours of different families or
//! classes differ by delta-E >= 20; members of 5-8 and 9-16 by >= 10; members of 17-64 by >= 5
//! (48 shades of one hue cannot all be told apart: the family is read as "long period", and the
//! legend names every member shown).

/// Colours of the attractors of a basin map, by rank (most cells first): the seven Okabe-Ito
/// colours, then hues and lightnesses none of them has. Attractors beyond the list are drawn as
/// "other" (grey); failed cells keep the class map's magenta. Pairwise delta-E >= 20
/// (`tests/figures.rs`).
pub const ATTRACTOR_COLORS: [[u8; 3]; 12] = [
    [0x00, 0x72, 0xb2],
    [0xe6, 0x9f, 0x00],
    [0x00, 0x9e, 0x73],
    [0xd5, 0x5e, 0x00],
    [0x56, 0xb4, 0xe9],
    [0xcc, 0x79, 0xa7],
    [0xf0, 0xe4, 0x42],
    [0x1a, 0x1a, 0x1a],
    [0x8c, 0x51, 0x0a],
    [0x5e, 0x3c, 0x99],
    [0x9a, 0xd0, 0x8a],
    [0x01, 0x45, 0x4d],
];

use crate::class::{MAX_PERIOD, Shown};

/// The colour of what a class-map cell shows.
pub fn color(s: Shown) -> [u8; 3] {
    s.rgb(period_color)
}

/// Colour of period `n` (1..=64; longer periods are not detected and get the 17-64 family's
/// last shade).
pub fn period_color(n: u32) -> [u8; 3] {
    match n {
        0 | 1 => [0x00, 0x72, 0xb2],
        2 => [0xe6, 0x9f, 0x00],
        3 => [0x00, 0x9e, 0x73],
        4 => [0xcc, 0x79, 0xa7],
        5..=8 => lch(25.0 + 12.0 * f64::from(n - 5), 45.0, 295.0),
        9..=16 => {
            // The hue alternates a little, because yellow's chroma limit at high lightness
            // leaves lightness steps alone too close.
            let k = n - 9;
            let h = if k.is_multiple_of(2) { 102.0 } else { 88.0 };
            lch(40.0 + 7.3 * f64::from(k), 60.0, h)
        }
        _ => {
            // Six lightness levels cycle fastest, so neighbouring periods differ most;
            // chroma and hue select the cycle.
            let k = n.clamp(17, MAX_PERIOD) - 17;
            const L: [f64; 6] = [24.0, 33.0, 42.0, 51.0, 60.0, 69.0];
            const H: [f64; 4] = [20.0, 34.0, 48.0, 62.0];
            let v = (k / 6) as usize;
            let c = if v < 4 { 25.0 } else { 48.0 };
            lch(L[k as usize % 6], c, H[v % 4])
        }
    }
}

/// sRGB of CIE LCh (D65), chroma reduced until the colour is inside the sRGB gamut.
fn lch(l: f64, c: f64, h_deg: f64) -> [u8; 3] {
    let (s, co) = h_deg.to_radians().sin_cos();
    let mut c = c;
    loop {
        let rgb = lab_to_linear_rgb(l, c * co, c * s);
        if rgb.iter().all(|v| (-1e-9..=1.0 + 1e-9).contains(v)) || c < 0.5 {
            return rgb.map(|v| {
                let v = v.clamp(0.0, 1.0);
                let g = if v <= 0.003_130_8 {
                    12.92 * v
                } else {
                    1.055 * v.powf(1.0 / 2.4) - 0.055
                };
                (255.0 * g).round() as u8
            });
        }
        c *= 0.97;
    }
}

fn lab_to_linear_rgb(l: f64, a: f64, b: f64) -> [f64; 3] {
    let fy = (l + 16.0) / 116.0;
    let (fx, fz) = (fy + a / 500.0, fy - b / 200.0);
    let d = 6.0 / 29.0;
    let finv = |t: f64| {
        if t > d {
            t * t * t
        } else {
            3.0 * d * d * (t - 4.0 / 29.0)
        }
    };
    let (x, y, z) = (0.95047 * finv(fx), finv(fy), 1.08883 * finv(fz));
    [
        3.2406 * x - 1.5372 * y - 0.4986 * z,
        -0.9689 * x + 1.8758 * y + 0.0415 * z,
        0.0557 * x - 0.2040 * y + 1.0570 * z,
    ]
}
