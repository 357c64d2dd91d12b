//! The Python class body that the planar (`Walker`) and the 3-D (`Walker3d`) SIMBICON walkers
//! share: pickling, the scene's undo point, stepping, pushes, views and drawing. Each walker's
//! own constructor and controller accessors are passed in.

/// Defines the pyclass `$name` around the walker `$core` (drawn with the boxes of `$boxes`),
/// with the shared methods and the methods given in the braces.
macro_rules! walker_class {
    ($(#[$doc:meta])* $name:ident($core:ty, $boxes:path) { $($own:tt)* }) => {
        $(#[$doc])*
        #[pyclass(module = "kinema._kinema")]
        pub struct $name {
            walker: $core,
            /// The undo point of `_mark` (state, phase and colliders; none before the
            /// first).
            saved: Option<(
                crate::character::State,
                crate::character::Phase,
                Vec<crate::character::Collider>,
            )>,
        }

        #[pymethods]
        impl $name {
            /// Pickle support: the walker as a snapshot (model, state, phase, controller).
            fn __reduce__<'py>(
                slf: &Bound<'py, Self>,
            ) -> PyResult<super::pickle::Reduced<'py>> {
                super::pickle::reduce(slf, |s| &s.walker, vec![])
            }

            /// The object stored by `__reduce__`.
            #[staticmethod]
            fn _from_snapshot(data: &[u8]) -> PyResult<Self> {
                use crate::snapshot::Snapshot;
                Ok(Self { walker: <$core>::from_snapshot(data)?, saved: None })
            }

            /// Remember the state, the controller's phase and the colliders (a scene's
            /// undo point).
            fn _mark(&mut self) {
                let (walker, phase) = (&self.walker, self.walker.phase());
                match &mut self.saved {
                    Some((state, saved, colliders)) => {
                        state.clone_from(walker.state());
                        *saved = phase;
                        colliders.clear();
                        colliders.extend_from_slice(walker.model().colliders());
                    }
                    None => {
                        let colliders = walker.model().colliders().to_vec();
                        self.saved = Some((walker.state().clone(), phase, colliders));
                    }
                }
            }

            /// Put the state, the phase and the colliders back as they were at the last
            /// `_mark`.
            fn _rollback(&mut self) {
                if let Some((state, phase, colliders)) = &self.saved {
                    self.walker.restore(state, *phase);
                    self.walker.restore_colliders(colliders);
                }
            }

            /// The gait: `(lift, strike, [duration, kp, kd, torso_kp, torso_kd, max_torque])`.
            fn gait(&self) -> ([f64; 8], [f64; 8], [f64; 6]) {
                super::character::gait_values(&self.walker.gait)
            }

            /// Advance `steps` steps of `dt` seconds (GIL released).
            fn step(
                &mut self,
                py: Python<'_>,
                dt: f64,
                steps: super::args::Int,
            ) -> PyResult<()> {
                let steps = steps.count("steps")?;
                let walker = &mut self.walker;
                super::error::detached(py, || walker.step(dt, steps))
            }

            /// Add a collider of kind `kind` with the shape's parameters `p`
            /// (`super::geometry::shape`), Coulomb `friction` (None: the ground's),
            /// `velocity` (m/s, world) and `angular_velocity` (rad/s, world, about its
            /// centre; it is at `p` now); returns its index.
            fn add_collider(
                &mut self,
                kind: &str,
                p: Vec<f64>,
                friction: Option<f64>,
                velocity: [f64; 3],
                angular_velocity: [f64; 3],
            ) -> PyResult<usize> {
                let since = self.walker.state().time();
                let c = super::character::moving_collider(
                    (kind, &p), friction, velocity, angular_velocity, since,
                )?;
                let index = self.walker.add_collider(c.shape, friction)?;
                self.walker.set_collider(index, c)?;
                Ok(index)
            }

            /// Move collider `index` to the shape `p` of kind `kind` (same kind and size) at
            /// the walker's current time, translating at `velocity` (m/s, world) and turning
            /// at `angular_velocity` (rad/s, world, about its centre) from then on.
            fn set_collider(
                &mut self,
                index: super::args::Int,
                kind: &str,
                p: Vec<f64>,
                friction: Option<f64>,
                velocity: [f64; 3],
                angular_velocity: [f64; 3],
            ) -> PyResult<()> {
                let index = index.count("index")?;
                let since = self.walker.state().time();
                let c = super::character::moving_collider(
                    (kind, &p), friction, velocity, angular_velocity, since,
                )?;
                Ok(self.walker.set_collider(index, c)?)
            }

            /// Push the torso (body 0) or another body with `force` (N, world) for
            /// `duration` s.
            fn push(&mut self, body: super::args::Int, force: [f64; 3], duration: f64) -> PyResult<()> {
                let body = body.count("body")?;
                let (model, state) = self.walker.parts_mut();
                Ok(state.push(model, body, glam::DVec3::from_array(force), duration)?)
            }

            /// Read-only view of the coordinates `(nq,)`, updated in place by `step`.
            #[getter]
            fn q<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, numpy::PyArrayDyn<f64>>> {
                let n = slf.borrow().walker.model().nq();
                super::view::view(slf, &[n], |r| r.walker.state().q())
            }

            /// Read-only view of the rates `(nv,)`, updated in place by `step`.
            #[getter]
            fn qd<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, numpy::PyArrayDyn<f64>>> {
                let n = slf.borrow().walker.model().nv();
                super::view::view(slf, &[n], |r| r.walker.state().qd())
            }

            /// Centre of mass (m, world).
            #[getter]
            fn com(&mut self) -> [f64; 3] {
                self.walker.com().to_array()
            }

            /// Whether the right and left feet touch the ground.
            #[getter]
            fn feet_in_contact(&mut self) -> (bool, bool) {
                let [r, l] = self.walker.feet_in_contact();
                (r, l)
            }

            /// `(FSM state, time in it (s), steps taken)`.
            fn phase(&self) -> (u8, f64, u64) {
                let p = self.walker.phase();
                (p.state, p.time, p.steps)
            }

            /// Simulated time (s).
            #[getter]
            fn time(&self) -> f64 {
                self.walker.state().time()
            }

            /// World positions of the body frames `(bodies, 3)` in m (a new array).
            fn positions<'py>(
                &mut self,
                py: Python<'py>,
            ) -> PyResult<Bound<'py, numpy::PyArrayDyn<f64>>> {
                let p: Vec<glam::DVec3> = self.walker.kinematics().positions().to_vec();
                super::array::compute::<3>(py, p.len(), &[3], |out| {
                    let out = super::array::zeroed(out);
                    out.iter_mut().zip(&p).for_each(|(o, v)| *o = v.to_array());
                    Ok(())
                })
            }

            /// World orientations of the body frames `(bodies, 4)` as (w, x, y, z) (a new
            /// array).
            fn orientations<'py>(
                &mut self,
                py: Python<'py>,
            ) -> PyResult<Bound<'py, numpy::PyArrayDyn<f64>>> {
                let r: Vec<glam::DQuat> = self.walker.kinematics().orientations().to_vec();
                super::array::compute::<4>(py, r.len(), &[4], |out| {
                    let out = super::array::zeroed(out);
                    out.iter_mut().zip(&r).for_each(|(o, q)| *o = [q.w, q.x, q.y, q.z]);
                    Ok(())
                })
            }

            /// The box drawn for each body, in its body frame: `(centre, half extents)` (m).
            #[staticmethod]
            fn link_boxes() -> Vec<([f64; 3], [f64; 3])> {
                $boxes().iter().map(|(c, h)| (c.to_array(), h.to_array())).collect()
            }

            /// Body names, in order.
            fn names(&self) -> Vec<String> {
                self.walker.model().bodies().iter().map(|b| b.name.clone()).collect()
            }

            $($own)*
        }
    };
}

pub(super) use walker_class;
