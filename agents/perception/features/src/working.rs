//! The working images: intensity for SURF and LN-SURF, the local space average colour image for
//! LSAC-SURF (thesis Algorithm 2), and the hard/soft classification near saturation.

use rayon::prelude::*;

use crate::image32::luma_f32;
use crate::{DetectorConfig, DetectorKind, FeatureClass, GrayImage32, IntegralImage, Keypoint, LsacSpace};

/// Buffers reused frame after frame.
#[derive(Debug, Default)]
pub(crate) struct Scratch {
    pub(crate) gray: GrayImage32,
    pub(crate) gray_integral: IntegralImage,
    channels: [GrayImage32; 3],
    channel_integrals: [IntegralImage; 3],
    lsac: GrayImage32,
    pub(crate) lsac_integral: IntegralImage,
}

impl Scratch {
    /// Fills the buffers `kind` needs from `image`.
    pub(crate) fn prepare(&mut self, kind: DetectorKind, image: &image::RgbImage, config: &DetectorConfig) {
        self.gray.luma_into(image);
        self.gray_integral.compute(&self.gray, kind == DetectorKind::LnSurf);
        if kind != DetectorKind::LsacSurf {
            return;
        }
        let (w, h) = (self.gray.width(), self.gray.height());
        self.lsac.resize(w, h);
        let radii = nested_radii(config.lsac_radius_px);
        let floor = config.lsac_min_average;
        match config.lsac_space {
            LsacSpace::Gray => {
                let (gray, ii) = (&self.gray, &self.gray_integral);
                self.lsac.as_mut_slice().par_chunks_mut(w).enumerate().for_each(|(y, row)| {
                    for (x, out) in row.iter_mut().enumerate() {
                        let i = gray.as_slice()[y * w + x];
                        *out = lsac_sample(i, local_average(ii, x, y, &radii), floor);
                    }
                });
            }
            LsacSpace::PerChannel => {
                for (c, (img, ii)) in self.channels.iter_mut().zip(self.channel_integrals.iter_mut()).enumerate() {
                    img.resize(w, h);
                    for (out, px) in img.as_mut_slice().iter_mut().zip(image.pixels()) {
                        *out = f32::from(px.0[c]);
                    }
                    ii.compute(img, false);
                }
                let (channels, iis) = (&self.channels, &self.channel_integrals);
                self.lsac.as_mut_slice().par_chunks_mut(w).enumerate().for_each(|(y, row)| {
                    for (x, out) in row.iter_mut().enumerate() {
                        let ratio = |c: usize| {
                            let i = channels[c].as_slice()[y * w + x];
                            lsac_sample(i, local_average(&iis[c], x, y, &radii), floor)
                        };
                        *out = luma_f32([ratio(0), ratio(1), ratio(2)]);
                    }
                });
            }
        }
        self.lsac_integral.compute(&self.lsac, false);
    }

    /// The integral image the Hessian runs on for `kind`.
    pub(crate) fn working(&self, kind: DetectorKind) -> &IntegralImage {
        match kind {
            DetectorKind::LsacSurf => &self.lsac_integral,
            DetectorKind::Surf | DetectorKind::LnSurf => &self.gray_integral,
        }
    }
}

/// Radii of the three nested boxes whose mean approximates the Gaussian local average.
fn nested_radii(radius: usize) -> [usize; 3] {
    [(radius / 3).max(1), (2 * radius / 3).max(1), radius.max(1)]
}

/// Mean of three nested clipped box means centred on `(x, y)`: a centre-weighted kernel, the
/// box-filter approximation of the Gaussian local space average (thesis Algorithm 2, line 8).
fn local_average(ii: &IntegralImage, x: usize, y: usize, radii: &[usize; 3]) -> f32 {
    let (w, h) = (ii.width(), ii.height());
    let mut total = 0.0;
    for &r in radii {
        let (x0, x1) = (x.saturating_sub(r), (x + r + 1).min(w));
        let (y0, y1) = (y.saturating_sub(r), (y + r + 1).min(h));
        total += ii.box_sum(x0, y0, x1, y1) / ((x1 - x0) * (y1 - y0)) as f32;
    }
    total / radii.len() as f32
}

/// Ebner's descriptor `I / (2 a)` (thesis eq. 4.17) scaled back to 8-bit units (x 255), so an
/// average-lit patch keeps about its intensity and one threshold serves SURF and LSAC-SURF.
fn lsac_sample(intensity: f32, average: f32, floor: f32) -> f32 {
    255.0 * intensity / (2.0 * average.max(floor))
}

/// Hard if the gray pixel under the keypoint lies strictly inside `band`, else soft.
pub(crate) fn classify(gray: &GrayImage32, kp: &Keypoint, band: Option<(u8, u8)>) -> FeatureClass {
    let Some((lower, upper)) = band else { return FeatureClass::Hard };
    let (x, y) = (kp.x.round().max(0.0) as usize, kp.y.round().max(0.0) as usize);
    match gray.get(x, y) {
        Some(v) if v > f32::from(lower) && v < f32::from(upper) => FeatureClass::Hard,
        _ => FeatureClass::Soft,
    }
}
