//! Colours: one distinct colour per body, greys for fixed bodies, the background and the ground.

/// sRGB colour (0..1 components) of body `index`: hues spread by the golden angle so that
/// neighbours in the scene file differ; fixed bodies are grey.
pub fn body_srgb(index: usize, fixed: bool) -> [f32; 3] {
    if fixed {
        return [0.55, 0.55, 0.57];
    }
    let hue = (index as f64 * 0.618_033_988_749_895 + 0.08).fract();
    // Alternate saturation and value a little so that hues that come close again still differ.
    let saturation = [0.62, 0.48, 0.70][index % 3];
    let value = [0.95, 0.85, 0.78][(index / 3) % 3];
    hsv_to_rgb(hue, saturation, value)
}

/// Colour of a body frozen after its state went non-finite.
pub const QUARANTINED_SRGB: [f32; 3] = [0.35, 0.05, 0.05];
/// Clear colour.
/// Asleep bodies keep their hue at this fraction of their linear brightness, halfway to grey,
/// so a resting pile reads as resting without losing which body is which.
pub fn asleep(linear: [f32; 3]) -> [f32; 3] {
    let grey = (linear[0] + linear[1] + linear[2]) / 3.0;
    linear.map(|c| 0.45 * (0.5 * c + 0.5 * grey))
}

pub const BACKGROUND_SRGB: [f32; 3] = [0.13, 0.14, 0.16];
/// The ground plane under the grid.
pub const GROUND_SRGB: [f32; 3] = [0.20, 0.21, 0.23];
pub const GRID_SRGB: [f32; 3] = [0.34, 0.36, 0.39];
pub const GRID_X_AXIS_SRGB: [f32; 3] = [0.62, 0.30, 0.30];
pub const GRID_Z_AXIS_SRGB: [f32; 3] = [0.30, 0.40, 0.66];

fn hsv_to_rgb(h: f64, s: f64, v: f64) -> [f32; 3] {
    let h6 = h * 6.0;
    let sector = h6.floor() as i64 % 6;
    let f = h6 - h6.floor();
    let (p, q, t) = (v * (1.0 - s), v * (1.0 - s * f), v * (1.0 - s * (1.0 - f)));
    let (r, g, b) = match sector {
        0 => (v, t, p),
        1 => (q, v, p),
        2 => (p, v, t),
        3 => (p, q, v),
        4 => (t, p, v),
        _ => (v, p, q),
    };
    [r as f32, g as f32, b as f32]
}

pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

pub fn linear(c: [f32; 3]) -> [f32; 3] {
    c.map(srgb_to_linear)
}

/// 8-bit sRGB bytes of an sRGB colour.
pub fn srgb_bytes(c: [f32; 3]) -> [u8; 3] {
    c.map(|x| (x.clamp(0.0, 1.0) * 255.0).round() as u8)
}

/// Green when a constraint holds, through yellow to red at `t` = 1 (and beyond).
pub fn violation_srgb(t: f64) -> [f32; 3] {
    let t = t.clamp(0.0, 1.0) as f32;
    if t <= 0.0 {
        [0.25, 0.85, 0.35]
    } else if t < 0.5 {
        let u = t / 0.5;
        [0.25 + 0.75 * u, 0.85 + 0.1 * u, 0.35 - 0.2 * u]
    } else {
        let u = (t - 0.5) / 0.5;
        [1.0, 0.95 - 0.75 * u, 0.15]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn neighbouring_bodies_get_distinct_colours() {
        let colours: Vec<[u8; 3]> = (0..64).map(|i| srgb_bytes(body_srgb(i, false))).collect();
        for i in 0..colours.len() {
            for j in i + 1..colours.len().min(i + 8) {
                let d: i32 = (0..3)
                    .map(|k| (colours[i][k] as i32 - colours[j][k] as i32).abs())
                    .sum();
                assert!(
                    d > 30,
                    "bodies {i} and {j}: {:?} vs {:?}",
                    colours[i],
                    colours[j]
                );
            }
        }
    }
}
