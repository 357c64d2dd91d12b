//! Biovision hierarchy (BVH): reader and forward kinematics; the writer is in `bvh/write.rs`,
//! the conversion from an Acclaim skeleton and motion in `bvh/from_asf.rs`.
//!
//! A BVH file is a `HIERARCHY` of joints — each with an `OFFSET` from its parent joint (in the
//! parent's frame), a list of `CHANNELS` and optionally an `End Site` — followed by a `MOTION`
//! section: `Frames: N`, `Frame Time: dt` and one line of channel values per frame.
//!
//! # Why not an Acclaim [`Skeleton`](super::Skeleton)
//!
//! In an ASF skeleton a bone's own dofs rotate its own segment (the tip moves with the bone's
//! rotation). In a BVH file a joint's rotation moves its *children*: the offset to a joint is
//! turned by the parent's rotation, and a joint with several children (hips, chest) turns all
//! of them at once. BVH joints may also carry position channels anywhere in the tree. Neither
//! fits a bone with a direction, a length and rotation dofs, so a BVH file is read into its own
//! [`BvhSkeleton`]; the per-frame values use the shared [`Motion`] type (so slicing works the
//! same).
//!
//! # Conventions (written down here and in docs/mocap.md)
//!
//! * Rotation channels compose **intrinsically in the order listed**: `Zrotation Yrotation
//!   Xrotation` is `R = Rz · Ry · Rx` (kinema's upper-case sequence `ZYX`), so `v_parent = R ·
//!   v_joint`. Angles are degrees in the file and radians in [`Motion::values`].
//! * Position channels give the joint's translation relative to its parent (in the parent's
//!   frame) and **replace** the matching component of `OFFSET`; an axis without a position
//!   channel keeps the offset's value. This is how Blender's importer reads a root (its
//!   `OFFSET` is the rest position, the channels the absolute position) and what files with six
//!   channels on every joint (the Bandai-Namco set) need, whose position channels repeat the
//!   offsets. Meredith & Maddock (2001) describe adding the root channels to the offset
//!   instead; the two readings agree whenever the offset is zero, as in the CMU conversions.
//!   Translation is applied before rotation, wherever the position channels are listed.
//! * Joint `j` with parent `p`: `R_j = R_p · R_local`, `p_j = p_p + R_p · t_local`; a root has
//!   the identity and the origin as its parent.
//! * Lengths stay in file units: BVH has no unit header (the CMU conversions use the ASF's
//!   units, 1/0.45 inch; others use centimetres or metres), and the ASF/AMC reader does not
//!   scale either.
//! * Several `ROOT`s are allowed; joints are stored in file order (depth first, parents first).

use super::parse::{err, number};
use super::{Dof, Motion};
use crate::error::{Error, Result};
use glam::{DQuat, DVec3};

mod from_asf;
mod write;
pub use from_asf::asf_to_bvh;
pub use write::write_bvh;

/// One joint of a BVH hierarchy, as read.
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug, PartialEq)]
pub struct BvhJoint {
    /// Joint name (inner whitespace collapsed to single spaces).
    pub name: String,
    /// Index of the parent joint in [`BvhSkeleton::joints`] (`None`: a `ROOT`).
    pub parent: Option<usize>,
    /// `OFFSET`: rest translation from the parent joint, in the parent's frame (file units).
    pub offset: DVec3,
    /// Channels in file order: [`Dof::Translation`] for `Xposition`..., [`Dof::Rotation`] for
    /// `Xrotation`...
    pub channels: Vec<Dof>,
    /// `OFFSET` of the joint's `End Site`, if it has one (file units, the joint's frame).
    pub end_site: Option<DVec3>,
}

/// A BVH hierarchy and the sampling of its motion.
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug, PartialEq)]
pub struct BvhSkeleton {
    /// Joints in file order: depth first, every parent before its children.
    pub joints: Vec<BvhJoint>,
    /// `Frame Time` of the motion (seconds per frame). Kept with the hierarchy because
    /// [`Motion`] holds values only.
    pub frame_time: f64,
}

fn channel(tok: &str) -> Option<Dof> {
    Some(match tok.to_ascii_lowercase().as_str() {
        "xposition" => Dof::Translation(0),
        "yposition" => Dof::Translation(1),
        "zposition" => Dof::Translation(2),
        "xrotation" => Dof::Rotation(0),
        "yrotation" => Dof::Rotation(1),
        "zrotation" => Dof::Rotation(2),
        _ => return None,
    })
}

fn channel_name(d: Dof) -> Option<&'static str> {
    match d {
        Dof::Translation(a) if a < 3 => Some(["Xposition", "Yposition", "Zposition"][a]),
        Dof::Rotation(a) if a < 3 => Some(["Xrotation", "Yrotation", "Zrotation"][a]),
        _ => None,
    }
}

/// An open block of the hierarchy while parsing.
enum Open {
    /// Joint index, line of its `ROOT`/`JOINT`.
    Joint(usize, usize),
    /// Owning joint, line of `End Site`, offset once read.
    EndSite(usize, usize, Option<DVec3>),
}

/// Tokens of the hierarchy with their 1-based line numbers.
struct Tokens<'a> {
    toks: Vec<(usize, &'a str)>,
    pos: usize,
    file: &'a str,
    last_line: usize,
}

impl<'a> Tokens<'a> {
    fn next(&mut self) -> Option<(usize, &'a str)> {
        let t = self.toks.get(self.pos).copied();
        self.pos += 1;
        t
    }

    /// The next token, or an error at the last line saying what was expected.
    fn expect(&mut self, what: &str) -> Result<(usize, &'a str)> {
        self.next()
            .ok_or_else(|| err(self.file, self.last_line, format!("{what} (file truncated?)")))
    }

    fn numbers<const N: usize>(&mut self, what: &str) -> Result<[f64; N]> {
        let mut v = [0.0; N];
        for x in &mut v {
            let (ln, t) = self.expect(what)?;
            *x = number(self.file, ln, t).map_err(|_| err(self.file, ln, what))?;
        }
        Ok(v)
    }
}

/// The value of a MOTION header line `key: value` (`Frames: 2752`, `Frame Time: .0083333`;
/// any case, spaces optional around the colon).
fn header_value<'a>(
    file: &str,
    last_line: usize,
    entry: Option<&(usize, &'a str)>,
    key: &str,
) -> Result<(usize, &'a str)> {
    let &(ln, line) =
        entry.ok_or_else(|| err(file, last_line, format!("a {key}: line after MOTION")))?;
    let words: Vec<&str> =
        line.split(|c: char| c.is_whitespace() || c == ':').filter(|w| !w.is_empty()).collect();
    let kw: Vec<&str> = key.split(' ').collect();
    let ok = line.contains(':')
        && words.len() == kw.len() + 1
        && words.iter().zip(&kw).all(|(w, k)| w.eq_ignore_ascii_case(k));
    if !ok {
        return Err(err(file, ln, format!("{key}: and a value")));
    }
    Ok((ln, words[kw.len()]))
}

/// The joints read so far from the hierarchy and the blocks still open.
struct Hierarchy<'a> {
    file: &'a str,
    joints: Vec<BvhJoint>,
    offset_seen: Vec<bool>,
    channels_seen: Vec<bool>,
    stack: Vec<Open>,
}

/// Parse a BVH file; `file` names it in errors.
///
/// Tolerates what real files contain: CRLF, tabs, blank lines, a byte-order mark, keywords in
/// any case, `{` on the joint's line, names with spaces, `Frames:2752` without a space, any
/// channel order and any number of channels per joint (3 and 6 in practice).
///
/// # Errors
/// [`Error::Parse`] with the line and what was expected: a missing `HIERARCHY`, `{`, `}`,
/// `OFFSET` or `MOTION`; an unknown keyword or channel; a bad or non-finite number; a frame
/// line with the wrong number of values; fewer or more frame lines than `Frames:` says.
pub fn parse_bvh(text: &str, file: &str) -> Result<(BvhSkeleton, Motion)> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let lines: Vec<(usize, &str)> = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty())
        .collect();
    let last_line = lines.last().map_or(1, |l| l.0);
    let motion_at = lines.iter().position(|(_, l)| {
        l.split_whitespace().next().is_some_and(|t| t.eq_ignore_ascii_case("MOTION"))
    });
    let header = &lines[..motion_at.unwrap_or(lines.len())];
    let mut toks = Tokens {
        toks: header
            .iter()
            .flat_map(|&(ln, l)| l.split_whitespace().map(move |t| (ln, t)))
            .collect(),
        pos: 0,
        file,
        // What the hierarchy misses is reported where it ends: at MOTION, or the last line.
        last_line: motion_at.map_or(last_line, |m| lines[m].0),
    };
    let joints = parse_hierarchy(&mut toks, last_line)?;
    let Some(motion_at) = motion_at else {
        return Err(err(file, last_line, "MOTION after the hierarchy (file truncated?)"));
    };
    let (frame_time, motion) = parse_motion(file, &lines[motion_at..], last_line, &joints)?;
    Ok((BvhSkeleton { joints, frame_time }, motion))
}

/// The joints of the `HIERARCHY` section (every token before `MOTION`).
fn parse_hierarchy(toks: &mut Tokens<'_>, last_line: usize) -> Result<Vec<BvhJoint>> {
    let file = toks.file;
    match toks.next() {
        Some((_, t)) if t.eq_ignore_ascii_case("HIERARCHY") => {}
        Some((ln, _)) => return Err(err(file, ln, "HIERARCHY at the start")),
        None => return Err(err(file, last_line, "HIERARCHY at the start, found nothing")),
    }
    let mut h = Hierarchy {
        file,
        joints: Vec::new(),
        offset_seen: Vec::new(),
        channels_seen: Vec::new(),
        stack: Vec::new(),
    };
    while let Some((ln, tok)) = toks.next() {
        match tok.to_ascii_lowercase().as_str() {
            key @ ("root" | "joint") => h.joint(toks, ln, tok, key == "root")?,
            "end" => h.end_site(toks, ln)?,
            "offset" => h.offset(toks, ln)?,
            "channels" => h.channels(toks, ln)?,
            "}" => h.close(ln)?,
            _ => {
                let what = match h.stack.last() {
                    None => "ROOT or MOTION",
                    Some(Open::Joint(..)) => "OFFSET, CHANNELS, JOINT, End Site or }",
                    Some(Open::EndSite(..)) => "OFFSET or } in an End Site",
                };
                return Err(err(file, ln, what));
            }
        }
    }
    if let Some(open) = h.stack.last() {
        let what = match open {
            Open::Joint(j, l) => {
                format!("}} to close joint {:?} opened at line {l}", h.joints[*j].name)
            }
            Open::EndSite(_, l, _) => format!("}} to close the End Site opened at line {l}"),
        };
        return Err(err(file, toks.last_line, format!("{what} (file truncated?)")));
    }
    if h.joints.is_empty() {
        return Err(err(file, toks.last_line, "a ROOT joint after HIERARCHY"));
    }
    Ok(h.joints)
}

impl Hierarchy<'_> {
    /// The joint whose block is innermost, if the innermost block is a joint.
    fn top_joint(&self) -> Option<usize> {
        match self.stack.last() {
            Some(Open::Joint(j, _)) => Some(*j),
            _ => None,
        }
    }

    /// `ROOT name {` or `JOINT name {` at line `ln`: open a new joint.
    fn joint(&mut self, toks: &mut Tokens<'_>, ln: usize, tok: &str, root: bool) -> Result<()> {
        let file = self.file;
        let parent = self.top_joint();
        if root && !self.stack.is_empty() {
            let what = "OFFSET, CHANNELS, JOINT, End Site or } inside a joint, found ROOT";
            return Err(err(file, ln, what));
        }
        if !root && parent.is_none() {
            let what = if self.stack.is_empty() {
                "ROOT at the top level, found JOINT"
            } else {
                "OFFSET or } in an End Site, found JOINT"
            };
            return Err(err(file, ln, what));
        }
        // The name is the rest of the keyword's line, up to a `{`.
        let mut name: Vec<&str> = Vec::new();
        let mut brace = false;
        while let Some(&(l, t)) = toks.toks.get(toks.pos) {
            if l != ln {
                break;
            }
            toks.pos += 1;
            if t == "{" {
                brace = true;
                break;
            }
            name.push(t);
        }
        if name.is_empty() {
            return Err(err(file, ln, format!("a joint name after {tok}")));
        }
        if !brace {
            let (l, t) = toks.expect("{ after the joint name")?;
            if t != "{" {
                return Err(err(file, l, "{ after the joint name"));
            }
        }
        self.joints.push(BvhJoint {
            name: name.join(" "),
            parent,
            offset: DVec3::ZERO,
            channels: Vec::new(),
            end_site: None,
        });
        self.offset_seen.push(false);
        self.channels_seen.push(false);
        self.stack.push(Open::Joint(self.joints.len() - 1, ln));
        Ok(())
    }

    /// `End Site {` at line `ln`.
    fn end_site(&mut self, toks: &mut Tokens<'_>, ln: usize) -> Result<()> {
        let file = self.file;
        let j = self.top_joint().ok_or_else(|| err(file, ln, "End Site only inside a joint"))?;
        let (l, t) = toks.expect("Site after End")?;
        if !t.eq_ignore_ascii_case("site") {
            return Err(err(file, l, "Site after End"));
        }
        let (l, t) = toks.expect("{ after End Site")?;
        if t != "{" {
            return Err(err(file, l, "{ after End Site"));
        }
        if self.joints[j].end_site.is_some() {
            let what = format!("one End Site in joint {:?}", self.joints[j].name);
            return Err(err(file, ln, what));
        }
        self.stack.push(Open::EndSite(j, ln, None));
        Ok(())
    }

    /// `OFFSET x y z` at line `ln`, of the innermost joint or End Site.
    fn offset(&mut self, toks: &mut Tokens<'_>, ln: usize) -> Result<()> {
        let file = self.file;
        let v = toks.numbers::<3>("three numbers after OFFSET")?;
        match self.stack.last_mut() {
            Some(Open::Joint(j, _)) => {
                if std::mem::replace(&mut self.offset_seen[*j], true) {
                    let what = format!("one OFFSET in joint {:?}", self.joints[*j].name);
                    return Err(err(file, ln, what));
                }
                self.joints[*j].offset = DVec3::from_array(v);
            }
            Some(Open::EndSite(_, _, o)) => {
                if o.replace(DVec3::from_array(v)).is_some() {
                    return Err(err(file, ln, "one OFFSET in an End Site"));
                }
            }
            None => return Err(err(file, ln, "ROOT before OFFSET")),
        }
        Ok(())
    }

    /// `CHANNELS n name…` at line `ln`, of the innermost joint.
    fn channels(&mut self, toks: &mut Tokens<'_>, ln: usize) -> Result<()> {
        let file = self.file;
        let j = self.top_joint().ok_or_else(|| {
            let what = if self.stack.is_empty() {
                "ROOT before CHANNELS"
            } else {
                "OFFSET or } in an End Site, found CHANNELS"
            };
            err(file, ln, what)
        })?;
        if std::mem::replace(&mut self.channels_seen[j], true) {
            let what = format!("one CHANNELS line in joint {:?}", self.joints[j].name);
            return Err(err(file, ln, what));
        }
        let (l, t) = toks.expect("a channel count after CHANNELS")?;
        let n: usize = t
            .parse()
            .ok()
            .filter(|&n| n <= 64)
            .ok_or_else(|| err(file, l, "a channel count (0 to 64) after CHANNELS"))?;
        let mut channels = Vec::with_capacity(n);
        for _ in 0..n {
            let (l, t) = toks.expect(&format!("{n} channel names"))?;
            let c = channel(t).ok_or_else(|| {
                err(file, l, format!("{n} channel names (Xposition ... Zrotation)"))
            })?;
            if matches!(c, Dof::Translation(_)) && channels.contains(&c) {
                return Err(err(file, l, format!("each position channel once, {t} is repeated")));
            }
            channels.push(c);
        }
        self.joints[j].channels = channels;
        Ok(())
    }

    /// `}` at line `ln`: close the innermost joint or End Site.
    fn close(&mut self, ln: usize) -> Result<()> {
        let file = self.file;
        match self.stack.pop() {
            Some(Open::Joint(j, _)) => {
                if !self.offset_seen[j] {
                    let what =
                        format!("an OFFSET in joint {:?} before its }}", self.joints[j].name);
                    return Err(err(file, ln, what));
                }
            }
            Some(Open::EndSite(j, _, o)) => {
                let o = o.ok_or_else(|| err(file, ln, "an OFFSET in the End Site before its }"))?;
                self.joints[j].end_site = Some(o);
            }
            None => return Err(err(file, ln, "ROOT or MOTION, found an unmatched }")),
        }
        Ok(())
    }
}

/// The `MOTION` section (`lines` from the `MOTION` line on): the frame time (s) and the
/// frames, rotations converted to radians.
fn parse_motion(
    file: &str,
    lines: &[(usize, &str)],
    last_line: usize,
    joints: &[BvhJoint],
) -> Result<(f64, Motion)> {
    let (mln, mline) = lines[0];
    if mline.split_whitespace().count() != 1 {
        return Err(err(file, mln, "MOTION alone on its line"));
    }
    // `Frames: N` and `Frame Time: dt`, in this order as every writer puts them.
    let mut rest = lines[1..].iter();
    let (fln, ftok) = header_value(file, last_line, rest.next(), "Frames")?;
    let frames: usize = ftok.parse().map_err(|_| err(file, fln, "a frame count after Frames:"))?;
    let (tln, ttok) = header_value(file, last_line, rest.next(), "Frame Time")?;
    let frame_time = number(file, tln, ttok)?;
    if frame_time <= 0.0 {
        return Err(err(file, tln, "a positive Frame Time"));
    }
    let stride: usize = joints.iter().map(|j| j.channels.len()).sum();
    let kinds: Vec<bool> = joints
        .iter()
        .flat_map(|j| j.channels.iter().map(|c| matches!(c, Dof::Rotation(_))))
        .collect();
    let mut values: Vec<f64> = Vec::with_capacity(rest.len().min(frames) * stride);
    let mut read = 0usize;
    for &(ln, line) in rest {
        if read == frames {
            let what = format!("the end of the file after {frames} frames (Frames: {frames})");
            return Err(err(file, ln, what));
        }
        frame_values(file, ln, line, &kinds, read, &mut values)?;
        read += 1;
    }
    if read < frames && stride > 0 {
        return Err(err(
            file,
            last_line,
            format!("{frames} frames (Frames: {frames}), found {read} (file truncated?)"),
        ));
    }
    Ok((frame_time, Motion { values, stride, frames, frame_rate: 1.0 / frame_time }))
}

/// Append the values of frame `read` (0-based), line `ln`, to `values`: one per channel,
/// rotations (`kinds[k]` true) converted from degrees to radians.
fn frame_values(
    file: &str,
    ln: usize,
    line: &str,
    kinds: &[bool],
    read: usize,
    values: &mut Vec<f64>,
) -> Result<()> {
    let stride = kinds.len();
    for (t, &rotation) in line.split_whitespace().zip(kinds) {
        let v = number(file, ln, t)?;
        values.push(if rotation { v.to_radians() } else { v });
    }
    let n = line.split_whitespace().count();
    if n != stride {
        return Err(err(file, ln, format!("{stride} values in frame {}, found {n}", read + 1)));
    }
    Ok(())
}

impl BvhSkeleton {
    /// Joint names in order.
    pub fn joint_names(&self) -> Vec<String> {
        self.joints.iter().map(|j| j.name.clone()).collect()
    }

    /// Values per frame of a motion of this skeleton (all channels of all joints).
    pub fn stride(&self) -> usize {
        self.joints.iter().map(|j| j.channels.len()).sum()
    }

    /// Check the hierarchy that forward kinematics, editing and the writer rely on, for one
    /// built by hand or restored from bytes (a parsed one always passes): joints, every
    /// parent before its children, finite offsets, position and rotation channels about x,
    /// y, z, a positive finite frame time.
    ///
    /// # Errors
    /// [`Error::InvalidInput`] (argument `"skeleton"`) naming the first bad joint.
    pub fn validate(&self) -> Result<()> {
        if !(self.frame_time.is_finite() && self.frame_time > 0.0) {
            return Err(Error::invalid("skeleton", "frame time must be positive and finite"));
        }
        if let Some(i) = self
            .joints
            .iter()
            .position(|j| !(j.offset.is_finite() && j.end_site.is_none_or(|e| e.is_finite())))
        {
            return Err(Error::invalid("skeleton", "offsets must be finite").at(i));
        }
        if self.joints.is_empty() {
            return Err(Error::invalid("skeleton", "has no joints"));
        }
        for (i, j) in self.joints.iter().enumerate() {
            if j.parent.is_some_and(|p| p >= i) {
                return Err(Error::invalid(
                    "skeleton",
                    "every parent must come before its children",
                )
                .at(i));
            }
            if j.channels.iter().any(|c| channel_name(*c).is_none()) {
                return Err(Error::invalid(
                    "skeleton",
                    "BVH channels are positions and rotations about x, y or z",
                )
                .at(i));
            }
        }
        Ok(())
    }

    /// [`BvhSkeleton::validate`], and `motion` made for this skeleton.
    fn validate_motion(&self, motion: &Motion) -> Result<()> {
        self.validate()?;
        if motion.stride != self.stride() || motion.values.len() != motion.frames * motion.stride {
            return Err(Error::invalid(
                "motion",
                format!(
                    "has {} values per frame, the skeleton needs {}",
                    motion.stride,
                    self.stride()
                ),
            ));
        }
        Ok(())
    }

    /// Forward kinematics of every frame: world positions `(frames, joints, 3)` of every joint
    /// (file units) and world orientations `(frames, joints, 4)` (`w, x, y, z`), in parallel
    /// over frames. End sites are not rows; they sit at `p_j + R_j · end_site`.
    ///
    /// # Errors
    /// A motion made for another skeleton, output slices of the wrong length, a skeleton whose
    /// parents do not come first.
    pub fn forward_kinematics(
        &self,
        motion: &Motion,
        positions: &mut [[f64; 3]],
        orientations: &mut [[f64; 4]],
    ) -> Result<()> {
        self.validate_motion(motion)?;
        let joints = self.joints.len();
        super::pose_frames(motion, joints, positions, orientations, |frame, pos, ori| {
            self.pose(frame, pos, ori);
        })
    }

    /// FK of one frame of values into `pos`/`ori` (one row per joint).
    fn pose(&self, frame: &[f64], pos: &mut [[f64; 3]], ori: &mut [[f64; 4]]) {
        let mut k = 0;
        let mut world: Vec<(DVec3, DQuat)> = Vec::with_capacity(self.joints.len());
        for (j, joint) in self.joints.iter().enumerate() {
            let mut t = joint.offset;
            let mut r = DQuat::IDENTITY;
            for c in &joint.channels {
                match *c {
                    Dof::Translation(a) => t[a] = frame[k],
                    Dof::Rotation(a) => {
                        let (s, c) = (0.5 * frame[k]).sin_cos();
                        let e = DVec3::AXES[a] * s;
                        // Intrinsic: each listed rotation is about the already-rotated axes.
                        r *= DQuat::from_xyzw(e.x, e.y, e.z, c);
                    }
                    Dof::Length => {}
                }
                k += 1;
            }
            let (p, q) = match joint.parent {
                Some(parent) => {
                    let (pp, pq) = world[parent];
                    (pp + pq * t, (pq * r).normalize())
                }
                None => (t, r.normalize()),
            };
            world.push((p, q));
            pos[j] = p.to_array();
            ori[j] = crate::rotation::quat_to_wxyz(q);
        }
    }
}
