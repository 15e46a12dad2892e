//! A single-channel `f32` image, the pipeline's working space.

/// Row-major single-channel image of `f32` samples (8-bit intensity units, not clamped).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct GrayImage32 {
    width: usize,
    height: usize,
    data: Vec<f32>,
}

impl GrayImage32 {
    /// A `width x height` image of zeros.
    pub fn new(width: usize, height: usize) -> Self {
        GrayImage32 {
            width,
            height,
            data: vec![0.0; width * height],
        }
    }

    /// Resizes in place (contents unspecified afterwards), reusing the allocation.
    pub fn resize(&mut self, width: usize, height: usize) {
        self.width = width;
        self.height = height;
        self.data.resize(width * height, 0.0);
    }

    /// Width, px.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height, px.
    pub fn height(&self) -> usize {
        self.height
    }

    /// The samples, row-major.
    pub fn as_slice(&self) -> &[f32] {
        &self.data
    }

    /// The samples, row-major, mutable.
    pub fn as_mut_slice(&mut self) -> &mut [f32] {
        &mut self.data
    }

    /// The sample at column `x`, row `y`, or `None` outside the image.
    pub fn get(&self, x: usize, y: usize) -> Option<f32> {
        if x < self.width {
            self.data.get(y * self.width + x).copied()
        } else {
            None
        }
    }

    /// Channel `c` (0 red, 1 green, 2 blue) of an RGB image.
    pub(crate) fn channel_into(&mut self, image: &image::RgbImage, c: usize) {
        self.resize(image.width() as usize, image.height() as usize);
        for (out, px) in self.data.iter_mut().zip(image.pixels()) {
            *out = f32::from(px.0[c]);
        }
    }

    /// Luma (0.299 R + 0.587 G + 0.114 B, ITU-R BT.601, as OpenCV's gray) of an RGB image.
    pub fn luma_into(&mut self, image: &image::RgbImage) {
        self.resize(image.width() as usize, image.height() as usize);
        for (out, px) in self.data.iter_mut().zip(image.pixels()) {
            *out = luma(px.0);
        }
    }

    /// Luma of three float channel planes of one size.
    pub(crate) fn luma_of(&mut self, [r, g, b]: [&GrayImage32; 3]) {
        self.resize(r.width, r.height);
        for (((out, &r), &g), &b) in self.data.iter_mut().zip(&r.data).zip(&g.data).zip(&b.data) {
            *out = luma_f32([r, g, b]);
        }
    }
}

/// BT.601 luma of one 8-bit RGB pixel.
fn luma([r, g, b]: [u8; 3]) -> f32 {
    luma_f32([f32::from(r), f32::from(g), f32::from(b)])
}

/// BT.601 luma weights of red, green and blue.
pub(crate) const LUMA_WEIGHTS: [f32; 3] = [0.299, 0.587, 0.114];

/// BT.601 luma of float channels.
fn luma_f32([r, g, b]: [f32; 3]) -> f32 {
    LUMA_WEIGHTS[0] * r + LUMA_WEIGHTS[1] * g + LUMA_WEIGHTS[2] * b
}
