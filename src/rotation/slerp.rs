//! Spherical linear interpolation (Shoemake 1985, "Animating rotation with quaternion
//! curves", SIGGRAPH): `slerp(q0, q1, t) = q0 (q0* q1)^t`, a constant-angular-speed path on
//! the great circle through `q0` and `q1`.

use glam::DQuat;

/// The rotation at parameter `t` on the great arc from `q0` (`t = 0`) to `q1` (`t = 1`).
///
/// `t` outside `[0, 1]` extrapolates along the same circle. With `shortest`, the relative
/// rotation `q0* q1` is taken with `w >= 0`, the arc of at most pi radians of rotation;
/// otherwise the arc through `q1` exactly as given (for `q1 = -q0` that is a full turn,
/// made about the `+x` axis since every axis is equally valid).
///
/// The power `(q0* q1)^t` is formed from the half-angle `atan2(|u|, w)` and the unit axis
/// `u/|u|`, so equal and nearly equal inputs give exact constant paths without dividing by
/// `sin θ` (the textbook formula's 0/0).
pub fn slerp(q0: DQuat, q1: DQuat, t: f64, shortest: bool) -> DQuat {
    let mut rel = q0.conjugate() * q1;
    if shortest && rel.w < 0.0 {
        rel = -rel;
    }
    let u = rel.xyz();
    let s = u.length();
    let half = s.atan2(rel.w); // half the rotation angle of `rel`, in [0, pi]
    let axis = if s > 0.0 {
        u / s
    } else if rel.w < 0.0 {
        glam::DVec3::X
    } else {
        return q0;
    };
    let (sn, cs) = (t * half).sin_cos();
    (q0 * DQuat::from_xyzw(axis.x * sn, axis.y * sn, axis.z * sn, cs)).normalize()
}
