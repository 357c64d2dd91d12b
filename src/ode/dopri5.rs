//! The Dormand–Prince 5(4) pair (Dormand & Prince 1980, "A family of embedded Runge–Kutta
//! formulae", J. Comp. Appl. Math. 6; Hairer, Nørsett & Wanner, *Solving ODEs I*, §II.5,
//! table 5.2): seven stages, the last at the new point (first same as last), fifth-order
//! solution propagated, fourth-order embedded estimate.

// Numeric kernels index several arrays in step; index loops read closest to the formulas.
#![allow(clippy::needless_range_loop)]

use super::adaptive::{Pair, Tolerance};
use super::OdeSystem;
use crate::error::Result;

const C: [f64; 7] = [0.0, 1.0 / 5.0, 3.0 / 10.0, 4.0 / 5.0, 8.0 / 9.0, 1.0, 1.0];
const A: [[f64; 6]; 7] = [
    [0.0; 6],
    [1.0 / 5.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [3.0 / 40.0, 9.0 / 40.0, 0.0, 0.0, 0.0, 0.0],
    [44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0, 0.0, 0.0, 0.0],
    [19372.0 / 6561.0, -25360.0 / 2187.0, 64448.0 / 6561.0, -212.0 / 729.0, 0.0, 0.0],
    [9017.0 / 3168.0, -355.0 / 33.0, 46732.0 / 5247.0, 49.0 / 176.0, -5103.0 / 18656.0, 0.0],
    [35.0 / 384.0, 0.0, 500.0 / 1113.0, 125.0 / 192.0, -2187.0 / 6784.0, 11.0 / 84.0],
];
/// Fifth-order weights minus the embedded fourth-order ones.
const E: [f64; 7] = [
    35.0 / 384.0 - 5179.0 / 57600.0,
    0.0,
    500.0 / 1113.0 - 7571.0 / 16695.0,
    125.0 / 192.0 - 393.0 / 640.0,
    -2187.0 / 6784.0 + 92097.0 / 339200.0,
    11.0 / 84.0 - 187.0 / 2100.0,
    -1.0 / 40.0,
];

/// The continuous extension of order 4 (Dormand & Prince 1986, as in Hairer's `dopri5.f` and
/// scipy's `RK45`): `y(t + θh) = y + h Σ_j (Σ_i k_i P_ij) θ^(j+1)`.
const P: [[f64; 4]; 7] = [
    [
        1.0,
        -8048581381.0 / 2820520608.0,
        8663915743.0 / 2820520608.0,
        -12715105075.0 / 11282082432.0,
    ],
    [0.0; 4],
    [
        0.0,
        131558114200.0 / 32700410799.0,
        -68118460800.0 / 10900136933.0,
        87487479700.0 / 32700410799.0,
    ],
    [0.0, -1754552775.0 / 470086768.0, 14199869525.0 / 1410260304.0, -10690763975.0 / 1880347072.0],
    [
        0.0,
        127303824393.0 / 49829197408.0,
        -318862633887.0 / 49829197408.0,
        701980252875.0 / 199316789632.0,
    ],
    [0.0, -282668133.0 / 205662961.0, 2019193451.0 / 616988883.0, -1453857185.0 / 822651844.0],
    [0.0, 40617522.0 / 29380423.0, -110615467.0 / 29380423.0, 69997945.0 / 29380423.0],
];

/// Dormand–Prince 5(4) as a [`Pair`].
pub(super) struct Dopri5;

impl Pair for Dopri5 {
    const STAGES: usize = 7;
    const ORDER: f64 = 5.0;
    const FACTORS: (f64, f64) = (0.2, 5.0);

    /// Stages 2 to 7 (the seventh at `t + h` on the fifth-order solution, which is `y_new`).
    fn stages<S: OdeSystem>(
        sys: &mut S,
        t: f64,
        h: f64,
        y: &[f64],
        k: &mut [Vec<f64>],
        y_new: &mut [f64],
    ) -> Result<usize> {
        for s in 1..7 {
            for i in 0..y.len() {
                y_new[i] = y[i] + h * (0..s).map(|j| A[s][j] * k[j][i]).sum::<f64>();
            }
            sys.rhs(t + C[s] * h, y_new, &mut k[s])?;
        }
        Ok(6)
    }

    /// The root-mean-square of the local error estimate `h Σ E_j k_j`, scaled per component.
    fn error(tol: &Tolerance, h: f64, k: &[Vec<f64>], y: &[f64], y_new: &[f64]) -> f64 {
        let sum = (0..y.len())
            .map(|i| {
                let e = h * (0..7).map(|j| E[j] * k[j][i]).sum::<f64>();
                (e / tol.scale(y[i], y_new[i])).powi(2)
            })
            .sum::<f64>();
        (sum / y.len().max(1) as f64).sqrt()
    }

    /// First same as last: the seventh stage is `f(t + h, y_new)`.
    fn advance<S: OdeSystem>(_: &mut S, _: f64, _: &[f64], k: &mut [Vec<f64>]) -> Result<usize> {
        k.swap(0, 6);
        Ok(0)
    }

    const DENSE: usize = 4;

    /// `d_j = h Σ_i k_i P_ij`; after [`Pair::advance`] the step's first stage is in `k[6]`
    /// and its last in `k[0]`.
    fn dense<S: OdeSystem>(
        _: &mut S,
        _: f64,
        h: f64,
        y: &[f64],
        _: &[f64],
        k: &mut [Vec<f64>],
        d: &mut [Vec<f64>],
    ) -> Result<usize> {
        for i in 0..y.len() {
            for j in 0..4 {
                d[j][i] = h * (0..7).map(|s| P[s][j] * k[[6, 1, 2, 3, 4, 5, 0][s]][i]).sum::<f64>();
            }
        }
        Ok(0)
    }

    fn interpolate(theta: f64, y: &[f64], d: &[Vec<f64>], out: &mut [f64]) {
        for i in 0..y.len() {
            out[i] =
                y[i] + theta * (d[0][i] + theta * (d[1][i] + theta * (d[2][i] + theta * d[3][i])));
        }
    }
}
