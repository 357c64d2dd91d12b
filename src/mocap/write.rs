//! ASF and AMC writers: the inverse of the readers, so that read → write → read gives the same
//! skeleton and motion (angles to within the rounding of the radian/degree conversion).

use super::{Dof, Motion, Skeleton};
use crate::error::{Error, Result};
use std::fmt::Write;

fn dof_name(d: Dof, upper: bool) -> String {
    let s = match d {
        Dof::Rotation(a) => ["rx", "ry", "rz"][a],
        Dof::Translation(a) => ["tx", "ty", "tz"][a],
        Dof::Length => "l",
    };
    if upper {
        s.to_uppercase()
    } else {
        s.to_string()
    }
}

/// The skeleton as ASF text (numbers in Rust's shortest round-trip form).
pub fn write_asf(sk: &Skeleton) -> String {
    let to_file = if sk.degrees { 180.0 / std::f64::consts::PI } else { 1.0 };
    let mut s = String::new();
    let _ = writeln!(s, "# ASF written by kinema");
    let _ = writeln!(s, ":version 1.10");
    let _ = writeln!(s, ":name {}", sk.name);
    let _ = writeln!(
        s,
        ":units\n  mass {:?}\n  length {:?}\n  angle {}",
        sk.mass_unit,
        sk.length_unit,
        if sk.degrees { "deg" } else { "rad" }
    );
    let order: Vec<String> = sk.root_order.iter().map(|d| dof_name(*d, true)).collect();
    let axis: String = sk.root_axis.axes.iter().map(|&a| ["X", "Y", "Z"][a]).collect();
    let (p, o) = (sk.root_position, sk.root_orientation_as_read);
    let _ = writeln!(s, ":root\n  order {}\n  axis {axis}", order.join(" "));
    let _ = writeln!(
        s,
        "  position {:?} {:?} {:?}\n  orientation {:?} {:?} {:?}",
        p.x, p.y, p.z, o[0], o[1], o[2]
    );
    let _ = writeln!(s, ":bonedata");
    for (i, b) in sk.bones.iter().enumerate() {
        let (a, ord) = &b.axis_as_read;
        let d = b.direction;
        let _ = writeln!(s, "  begin\n    id {}\n    name {}", i + 1, b.name);
        let _ =
            writeln!(s, "    direction {:?} {:?} {:?}\n    length {:?}", d.x, d.y, d.z, b.length);
        let _ = writeln!(s, "    axis {:?} {:?} {:?} {ord}", a[0], a[1], a[2]);
        if !b.dofs.is_empty() {
            let dofs: Vec<String> = b.dofs.iter().map(|d| dof_name(*d, false)).collect();
            let _ = writeln!(s, "    dof {}", dofs.join(" "));
            for (k, (l, dof)) in b.limits.iter().zip(&b.dofs).enumerate() {
                let f = if matches!(dof, Dof::Rotation(_)) { to_file } else { 1.0 };
                let _ = writeln!(
                    s,
                    "    {}({:?} {:?})",
                    if k == 0 { "limits " } else { "       " },
                    l.0 * f,
                    l.1 * f
                );
            }
        }
        let _ = writeln!(s, "  end");
    }
    let _ = writeln!(s, ":hierarchy\n  begin");
    let names = sk.joint_names();
    for (j, name) in names.iter().enumerate() {
        let kids: Vec<&str> = sk
            .bones
            .iter()
            .filter(|b| b.parent.map_or(0, |p| p + 1) == j)
            .map(|b| b.name.as_str())
            .collect();
        if !kids.is_empty() {
            let _ = writeln!(s, "    {name} {}", kids.join(" "));
        }
    }
    let _ = writeln!(s, "  end");
    s
}

/// The motion as AMC text for `sk`.
///
/// # Errors
/// A motion made for another skeleton.
pub fn write_amc(sk: &Skeleton, motion: &Motion) -> Result<String> {
    if motion.stride != sk.stride() {
        return Err(Error::invalid("motion", "was not made for this skeleton"));
    }
    let to_file = if sk.degrees { 180.0 / std::f64::consts::PI } else { 1.0 };
    let mut s = String::from("# AMC written by kinema\n:FULLY-SPECIFIED\n");
    if sk.degrees {
        s.push_str(":DEGREES\n");
    }
    for f in 0..motion.frames {
        let row = &motion.values[f * motion.stride..(f + 1) * motion.stride];
        let _ = writeln!(s, "{}", f + 1);
        let mut k = 0;
        let mut line = |name: &str, dofs: &[Dof], s: &mut String| {
            if dofs.is_empty() {
                return;
            }
            let _ = write!(s, "{name}");
            for d in dofs {
                let v = if matches!(d, Dof::Rotation(_)) { row[k] * to_file } else { row[k] };
                let _ = write!(s, " {v:?}");
                k += 1;
            }
            s.push('\n');
        };
        line("root", &sk.root_order, &mut s);
        for b in &sk.bones {
            line(&b.name, &b.dofs, &mut s);
        }
    }
    Ok(s)
}
