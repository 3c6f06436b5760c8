//! The rendered image: what every projector, the detector chain and the writers pass on.

use super::Quantity;

/// A rendered image: `rows × cols` values, row-major (pixel `(r, c)` at `r·cols + c`),
/// pixel (0, 0) as documented on [`crate::geometry::Detector`].
#[derive(Debug, Clone, PartialEq)]
pub struct Projection {
    /// Image height.
    pub rows: usize,
    /// Image width.
    pub cols: usize,
    /// Pixel values (f32, as written to files).
    pub data: Vec<f32>,
}

impl Projection {
    /// Value at `(row, col)`.
    pub fn at(&self, row: usize, col: usize) -> f32 {
        self.data[row * self.cols + col]
    }

    /// Applies `quantity` to line-integral values.
    pub fn to_quantity(&self, quantity: Quantity) -> Projection {
        Projection {
            rows: self.rows,
            cols: self.cols,
            data: self
                .data
                .iter()
                .map(|&l| quantity.from_line_integral(f64::from(l)) as f32)
                .collect(),
        }
    }
}
