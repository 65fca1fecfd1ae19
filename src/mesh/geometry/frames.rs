//! The print frame (Z up, the bed face at z = 0) and the glTF frame.

use super::*;

impl Marker {
    /// The level `p · down` of the face that lies on the bed: the most any
    /// point of the solid reaches along [`Marker::down`].
    pub fn bed_face_level(&self) -> f64 {
        let m = self.down.vector();
        self.bed_level
            .unwrap_or(self.plate.centre.dot(&m) + self.plate.half_extents.dot(&m.abs()))
    }

    /// The marker → print frame motion `p ↦ R·p + shift` of the STL: Z up,
    /// [`Marker::down`] pointing onto the bed, the bed face at z = 0.
    pub fn print_transform(&self) -> (Matrix3<f64>, Vector3<f64>) {
        (
            print_rotation(self.down),
            Vector3::new(0.0, 0.0, self.bed_face_level()),
        )
    }

    /// The part's extents in the print frame (x, y, z), mm, from
    /// [`Marker::bounds`] (so at most the blend depth too large: the bed
    /// check errs on the safe side).
    pub fn print_size_mm(&self) -> [f64; 3] {
        let (lo, hi) = self.bounds();
        let size = print_rotation(self.down).abs() * (hi - lo);
        [size.x, size.y, size.z]
    }
}

/// The object → print-frame rotation: the print frame is Z-up with the
/// mount axis pointing down (−Z) onto the bed; its X is the first object
/// axis perpendicular to the mount axis, and Y = Z × X. For the default
/// mount −y this is (x, y, z) → (x, −z, y).
pub fn print_rotation(mount: Axis) -> Matrix3<f64> {
    let up = -mount.vector();
    let k = (0..3)
        .find(|&k| up[k] == 0.0)
        .expect("an axis is perpendicular");
    let x = Vector3::from_fn(|r, _| if r == k { 1.0 } else { 0.0 });
    let y = up.cross(&x);
    Matrix3::from_rows(&[x.transpose(), y.transpose(), up.transpose()])
}

/// The object → glTF rotation: the print frame turned Y-up, (x, y, z)_print
/// → (x, z, −y). glTF's up (+Y) is again opposite the mount axis; for the
/// default mount −y it is the identity.
pub fn gltf_rotation(mount: Axis) -> Matrix3<f64> {
    let z_up_to_y_up = Matrix3::new(1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, -1.0, 0.0);
    z_up_to_y_up * print_rotation(mount)
}
