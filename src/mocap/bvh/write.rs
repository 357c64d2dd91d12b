//! The BVH writer: the inverse of the reader, so that read → write → read is the identity.

use super::{channel_name, BvhSkeleton};
use crate::error::{Error, Result};
use crate::mocap::{Dof, Motion};
use std::fmt::Write;

/// The skeleton and motion as BVH text: tabs for indentation, numbers in the shortest form
/// that reads back to the same `f64` (angles in degrees, chosen so that reading them back
/// gives the stored radians exactly), so read → write → read is the identity.
///
/// # Errors
/// A motion made for another skeleton; a skeleton that cannot be written as BVH (no joints,
/// a parent after its child, a `Length` dof, a name that is empty or has braces or untidy
/// whitespace); a non-finite value or a non-positive frame time.
pub fn write_bvh(skeleton: &BvhSkeleton, motion: &Motion) -> Result<String> {
    skeleton.validate_motion(motion)?;
    check_writable(skeleton, motion)?;
    let mut s = String::from("HIERARCHY\n");
    let columns = write_hierarchy(skeleton, &mut s);
    let _ = writeln!(s, "MOTION\nFrames: {}\nFrame Time: {}", motion.frames, skeleton.frame_time);
    for f in 0..motion.frames {
        let row = &motion.values[f * motion.stride..(f + 1) * motion.stride];
        for (i, &(c, rotation)) in columns.iter().enumerate() {
            if i > 0 {
                s.push(' ');
            }
            if rotation {
                s.push_str(&degrees_text(row[c]));
            } else {
                let _ = write!(s, "{}", row[c]);
            }
        }
        s.push('\n');
    }
    Ok(s)
}

/// What [`write_bvh`] needs beyond a valid skeleton and motion: a positive frame time, joint
/// names BVH can hold, finite offsets and values.
fn check_writable(sk: &BvhSkeleton, motion: &Motion) -> Result<()> {
    if !(sk.frame_time.is_finite() && sk.frame_time > 0.0) {
        return Err(Error::invalid(
            "frame_time",
            format!("must be positive, got {}", sk.frame_time),
        ));
    }
    for (i, j) in sk.joints.iter().enumerate() {
        let tidy = j.name.split_whitespace().collect::<Vec<_>>().join(" ");
        if j.name.is_empty() || tidy != j.name || j.name.contains(['{', '}']) {
            return Err(Error::invalid(
                "skeleton",
                format!("joint name {:?} cannot be written to BVH", j.name),
            )
            .at(i));
        }
        let finite = j.offset.is_finite() && j.end_site.is_none_or(|e| e.is_finite());
        if !finite {
            return Err(Error::invalid("skeleton", "non-finite offset").at(i));
        }
    }
    if let Some(i) = motion.values.iter().position(|v| !v.is_finite()) {
        return Err(
            Error::invalid("motion", "contains NaN or infinity").at(i / motion.stride.max(1))
        );
    }
    Ok(())
}

/// Write the `HIERARCHY` section's joints into `s`, children in index order, depth first (an
/// explicit stack, so deep hierarchies cannot overflow); returns the motion columns in the
/// order the joints are written: `(column of the motion, is a rotation)`.
fn write_hierarchy(sk: &BvhSkeleton, s: &mut String) -> Vec<(usize, bool)> {
    let n = sk.joints.len();
    let mut children: Vec<Vec<usize>> = vec![Vec::new(); n];
    for (i, j) in sk.joints.iter().enumerate() {
        if let Some(p) = j.parent {
            children[p].push(i);
        }
    }
    let mut first_channel = Vec::with_capacity(n);
    let mut k = 0;
    for j in &sk.joints {
        first_channel.push(k);
        k += j.channels.len();
    }
    let mut columns = Vec::with_capacity(k);
    // (joint, depth, closing?)
    let roots = (0..n).filter(|&i| sk.joints[i].parent.is_none());
    let mut stack: Vec<(usize, usize, bool)> = roots.rev().map(|r| (r, 0, false)).collect();
    while let Some((j, depth, closing)) = stack.pop() {
        let joint = &sk.joints[j];
        let ind = "\t".repeat(depth);
        if closing {
            if let Some(e) = joint.end_site {
                let _ = writeln!(
                    s,
                    "{ind}\tEnd Site\n{ind}\t{{\n{ind}\t\tOFFSET {} {} {}\n{ind}\t}}",
                    e.x, e.y, e.z
                );
            }
            let _ = writeln!(s, "{ind}}}");
            continue;
        }
        let o = joint.offset;
        let kw = if joint.parent.is_none() { "ROOT" } else { "JOINT" };
        let _ =
            writeln!(s, "{ind}{kw} {}\n{ind}{{\n{ind}\tOFFSET {} {} {}", joint.name, o.x, o.y, o.z);
        let names: Vec<&str> = joint.channels.iter().filter_map(|c| channel_name(*c)).collect();
        let _ = writeln!(
            s,
            "{ind}\tCHANNELS {}{}{}",
            names.len(),
            if names.is_empty() { "" } else { " " },
            names.join(" ")
        );
        for (c, ch) in joint.channels.iter().enumerate() {
            columns.push((first_channel[j] + c, matches!(ch, Dof::Rotation(_))));
        }
        stack.push((j, depth, true));
        stack.extend(children[j].iter().rev().map(|&c| (c, depth + 1, false)));
    }
    columns
}

/// Shortest fixed-point text of `rad` in degrees that reads back (through `to_radians`, as the
/// reader does) to exactly `rad`: `-3.2316°` stays `-3.2316`, not `-3.2316000000000003`.
fn degrees_text(rad: f64) -> String {
    let deg = rad.to_degrees();
    for decimals in 0..=17 {
        let s = format!("{deg:.decimals$}");
        if s.parse::<f64>().is_ok_and(|v| v.to_radians() == rad) {
            return s;
        }
    }
    format!("{deg}")
}
