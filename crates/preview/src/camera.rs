//! Pinhole cameras: one that frames a bounding box from a given direction, or one placed by a
//! camera node of the file.

use crate::math::{self, Vec3};
use crate::scene::{Bounds, CameraNode};

/// The vertical field of view of a framing camera (45°).
pub const FRAMING_YFOV: f64 = std::f64::consts::FRAC_PI_4;
/// Room left around the framed box, as a fraction of the frame.
const FRAMING_MARGIN: f64 = 0.04;

/// A perspective camera. View space: `x` right, `y` up, `z` the distance in front of the eye
/// along `forward`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub eye: Vec3,
    /// Unit vectors: right, up and the viewing direction (orthonormal).
    pub right: Vec3,
    pub up: Vec3,
    pub forward: Vec3,
    /// Vertical field of view, radians.
    pub yfov: f64,
    /// Width / height of the image.
    pub aspect: f64,
    /// Geometry nearer than this (view-space z) is clipped.
    pub znear: f64,
}

impl Camera {
    /// A camera looking along `view` (need not be unit length) that frames `bounds`: every
    /// corner of the box projects inside the image, with a small margin. The image's up is the
    /// world's +Y (or −Z when looking straight up or down). `None` when `view` is zero or not
    /// finite.
    pub fn framing(bounds: &Bounds, view: Vec3, aspect: f64) -> Option<Camera> {
        let forward = math::normalize(view)?;
        let (right, up) = basis(forward)?;
        let centre = math::scale(math::add(bounds.min, bounds.max), 0.5);
        let tan_y = (FRAMING_YFOV / 2.0).tan() * (1.0 - FRAMING_MARGIN);
        let tan_x = tan_y * aspect;
        // A corner at view offsets (x, y) and depth −z behind the centre is in frame when the
        // eye is at least z + |x| / tan_x (and z + |y| / tan_y) from the centre.
        let mut distance: f64 = 0.0;
        let mut nearest: f64 = f64::INFINITY;
        for corner in 0..8 {
            let p: Vec3 = std::array::from_fn(|axis| {
                if corner >> axis & 1 == 1 {
                    bounds.max[axis]
                } else {
                    bounds.min[axis]
                }
            });
            let offset = math::sub(p, centre);
            let x = math::dot(offset, right);
            let y = math::dot(offset, up);
            let towards_eye = -math::dot(offset, forward);
            distance = distance.max(towards_eye + (x.abs() / tan_x).max(y.abs() / tan_y));
            nearest = nearest.min(-towards_eye);
        }
        let size = math::length(math::sub(bounds.max, bounds.min));
        if !(distance.is_finite() && size.is_finite()) {
            return None;
        }
        // Only a box that is a single point frames at distance 0: step back from it.
        let distance = if distance > 0.0 {
            distance
        } else {
            size.max(1.0)
        };
        let eye = math::sub(centre, math::scale(forward, distance));
        // Every corner is at view depth ≥ distance + nearest > 0: clip well before that.
        let znear = ((distance + nearest) * 0.5).max(distance * 1e-6);
        Some(Camera {
            eye,
            right,
            up,
            forward,
            yfov: FRAMING_YFOV,
            aspect,
            znear,
        })
    }

    /// A camera at `eye` looking at `target` with vertical field of view `yfov` (radians), the
    /// image's up as close to the world's +Y as the view allows (−Z when looking straight up
    /// or down). Geometry nearer than 1e-4 of the eye–target distance is clipped. `None` when
    /// the points coincide or are not finite.
    pub fn looking_at(eye: Vec3, target: Vec3, yfov: f64, aspect: f64) -> Option<Camera> {
        if !eye.iter().chain(&target).all(|v| v.is_finite()) {
            return None;
        }
        let offset = math::sub(target, eye);
        let forward = math::normalize(offset)?;
        let (right, up) = basis(forward)?;
        Some(Camera {
            eye,
            right,
            up,
            forward,
            yfov,
            aspect,
            znear: math::length(offset) * 1e-4,
        })
    }

    /// The camera of a camera node (its world matrix's scale is ignored). `None` when the
    /// node's matrix or the camera's parameters are degenerate.
    pub fn from_node(node: &CameraNode, aspect: f64) -> Option<Camera> {
        let eye = math::transform_point(&node.world, [0.0; 3]);
        let forward = math::normalize(math::transform_vector(&node.world, [0.0, 0.0, -1.0]))?;
        let up_hint = math::transform_vector(&node.world, [0.0, 1.0, 0.0]);
        let right = math::normalize(math::cross(forward, up_hint))?;
        let up = math::cross(right, forward);
        let valid = node.yfov.is_finite()
            && node.yfov > 0.0
            && node.yfov < std::f64::consts::PI
            && node.znear.is_finite()
            && node.znear > 0.0
            && eye.iter().all(|v| v.is_finite());
        valid.then_some(Camera {
            eye,
            right,
            up,
            forward,
            yfov: node.yfov,
            aspect,
            znear: node.znear,
        })
    }

    /// `p` in view space: (right, up, depth in front of the eye).
    pub fn to_view(&self, p: Vec3) -> Vec3 {
        let d = math::sub(p, self.eye);
        [
            math::dot(d, self.right),
            math::dot(d, self.up),
            math::dot(d, self.forward),
        ]
    }

    /// A view-space point in pixel coordinates of a `width` × `height` image: x to the right,
    /// y down, pixel (i, j) covering [i, i + 1) × [j, j + 1). Only meaningful for z > 0.
    pub fn view_to_pixel(&self, v: Vec3, width: u32, height: u32) -> [f64; 2] {
        let tan_y = (self.yfov / 2.0).tan();
        let tan_x = tan_y * self.aspect;
        let ndc_x = v[0] / (v[2] * tan_x);
        let ndc_y = v[1] / (v[2] * tan_y);
        [
            (ndc_x + 1.0) * 0.5 * f64::from(width),
            (1.0 - ndc_y) * 0.5 * f64::from(height),
        ]
    }

    /// Where world point `p` lands in a `width` × `height` image (pixel coordinates as in
    /// [`Camera::view_to_pixel`]), or `None` when it is nearer than `znear` or behind the eye.
    pub fn project(&self, p: Vec3, width: u32, height: u32) -> Option<[f64; 2]> {
        let v = self.to_view(p);
        (v[2] >= self.znear).then(|| self.view_to_pixel(v, width, height))
    }
}

/// Right and up for the unit viewing direction `forward`: up as close to the world's +Y as
/// the view allows (−Z when looking straight up or down).
fn basis(forward: Vec3) -> Option<(Vec3, Vec3)> {
    let world_up = if forward[1].abs() > 0.999 {
        [0.0, 0.0, -forward[1].signum()]
    } else {
        [0.0, 1.0, 0.0]
    };
    let right = math::normalize(math::cross(forward, world_up))?;
    Some((right, math::cross(right, forward)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The target projects to the image's centre, a point on the camera's up axis above it,
    /// and the field of view's edge to the image's top edge.
    #[test]
    fn looking_at_centres_the_target() {
        let (eye, target) = ([1.0, 1.6, 3.5], [6.0, 0.8, 1.0]);
        let yfov = 75f64.to_radians();
        let camera = Camera::looking_at(eye, target, yfov, 2.0).expect("a camera");
        let centre = camera.project(target, 400, 200).expect("in front");
        assert!((centre[0] - 200.0).abs() < 1e-9 && (centre[1] - 100.0).abs() < 1e-9);
        let distance = math::length(math::sub(target, eye));
        let top = math::add(
            target,
            math::scale(camera.up, distance * (yfov / 2.0).tan()),
        );
        let edge = camera.project(top, 400, 200).expect("in front");
        assert!(
            (edge[0] - 200.0).abs() < 1e-9 && edge[1].abs() < 1e-9,
            "{edge:?}"
        );
        assert!(camera.up[1] > 0.0, "up stays up");
        assert!(Camera::looking_at(eye, eye, yfov, 1.0).is_none());
        assert!(Camera::looking_at([f64::NAN, 0.0, 0.0], target, yfov, 1.0).is_none());
    }
}
