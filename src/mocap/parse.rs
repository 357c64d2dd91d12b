//! ASF and AMC readers: text in, typed [`Skeleton`] / [`Motion`] out, or an error with the
//! file, the line and what was expected. Tolerant of what real files contain: comments,
//! blank lines, CRLF, tabs, limits spread over several lines, bones without dofs, AMC headers
//! such as `:FULLY-SPECIFIED` and `:DEGREES`.

use super::{Bone, Dof, Motion, Skeleton};
use crate::error::{Error, Result};
use crate::rotation::EulerSequence;
use glam::{DQuat, DVec3};
use std::collections::HashMap;

/// The parse error at `line` of `file`: `expected` is what should have been there.
pub(super) fn err(file: &str, line: usize, expected: impl Into<String>) -> Error {
    Error::Parse { file: file.to_string(), line, expected: expected.into() }
}

/// Lines without comments and surrounding blanks, with their 1-based numbers.
fn lines(text: &str) -> Vec<(usize, &str)> {
    text.lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.split('#').next().unwrap_or("").trim()))
        .filter(|(_, l)| !l.is_empty())
        .collect()
}

/// A finite number, or the parse error at `line` of `file`.
pub(super) fn number(file: &str, line: usize, tok: &str) -> Result<f64> {
    tok.parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
        .ok_or_else(|| err(file, line, "a finite number"))
}

/// Three finite numbers from `toks` (exactly three tokens).
fn three(file: &str, line: usize, toks: &[&str]) -> Result<[f64; 3]> {
    Ok([number(file, line, toks[0])?, number(file, line, toks[1])?, number(file, line, toks[2])?])
}

/// A limit: a number or `inf` / `-inf` (the ASF 1.10 text writes `limits (-inf inf)` for a
/// free dof), never NaN.
fn limit(file: &str, line: usize, tok: &str) -> Result<f64> {
    tok.parse::<f64>()
        .ok()
        .filter(|v| !v.is_nan())
        .ok_or_else(|| err(file, line, "a limit (a number, inf or -inf)"))
}

fn dof(file: &str, line: usize, tok: &str) -> Result<Dof> {
    Ok(match tok.to_ascii_lowercase().as_str() {
        "rx" => Dof::Rotation(0),
        "ry" => Dof::Rotation(1),
        "rz" => Dof::Rotation(2),
        "tx" => Dof::Translation(0),
        "ty" => Dof::Translation(1),
        "tz" => Dof::Translation(2),
        "l" => Dof::Length,
        _ => return Err(err(file, line, "a dof among rx ry rz tx ty tz l")),
    })
}

/// Extrinsic rotation about the global axes in the written order (`XYZ`: x first).
fn axis_rotation(file: &str, line: usize, angles: [f64; 3], order: &str) -> Result<DQuat> {
    let seq = EulerSequence::parse(&order.to_ascii_lowercase())
        .map_err(|_| err(file, line, "an axis order such as XYZ"))?;
    if seq.is_proper() {
        return Err(err(file, line, "an order of three different axes"));
    }
    let a = seq.axes.map(|i| angles[i]);
    seq.to_quat(&a).map_err(|_| err(file, line, "finite axis angles"))
}

/// A bone as read from `:bonedata`, before the hierarchy orders it: the bone, its `axis`
/// angles and order as written, and the line of its `begin`.
type RawBone = (Bone, [f64; 3], String, usize);

/// The state of an ASF reader between lines: what the sections have given so far.
struct AsfReader<'a> {
    file: &'a str,
    sk: Skeleton,
    /// The `:root` orientation as written and its line.
    root_orientation: ([f64; 3], usize),
    bones: Vec<RawBone>,
    /// The bone between `begin` and `end`.
    current: Option<RawBone>,
    /// Limits still expected on the following lines: dof count and the values read.
    pending_limits: Option<(usize, Vec<f64>)>,
    /// `:hierarchy` lines: line, parent, children.
    children: Vec<(usize, String, Vec<String>)>,
    seen_hierarchy: bool,
}

/// Parse an Acclaim skeleton file; `file` names it in errors.
///
/// # Errors
/// [`Error::Parse`] with the line and what was expected: unknown sections or keywords,
/// malformed numbers, limits that do not match the dofs, unknown or repeated bone names, bones
/// missing from or cyclic in the hierarchy.
pub fn parse_asf(text: &str, file: &str) -> Result<Skeleton> {
    let mut r = AsfReader {
        file,
        sk: Skeleton {
            name: String::new(),
            length_unit: 1.0,
            mass_unit: 1.0,
            degrees: true,
            root_order: Vec::new(),
            root_axis: EulerSequence::parse("xyz")?,
            root_position: DVec3::ZERO,
            root_orientation: DQuat::IDENTITY,
            root_orientation_as_read: [0.0; 3],
            bones: Vec::new(),
        },
        root_orientation: ([0.0; 3], 0),
        bones: Vec::new(),
        current: None,
        pending_limits: None,
        children: Vec::new(),
        seen_hierarchy: false,
    };
    let lines = lines(text);
    let mut section = "";
    for &(ln, line) in &lines {
        let toks: Vec<&str> = line.split_whitespace().collect();
        if let Some(name) = toks[0].strip_prefix(':') {
            section = r.section(ln, name, &toks)?;
            continue;
        }
        match section {
            "skip" => {}
            "units" => r.units(ln, &toks)?,
            "root" => r.root(ln, &toks)?,
            "bonedata" => r.bonedata(ln, line, &toks)?,
            "hierarchy" => r.hierarchy(ln, &toks),
            _ => return Err(err(file, ln, "a section header such as :units before data")),
        }
    }
    r.finish(lines.last().map_or(1, |l| l.0))
}

impl AsfReader<'_> {
    /// The section a `:name` header opens (`"skip"` for those without data kinema reads).
    fn section(&mut self, ln: usize, name: &str, toks: &[&str]) -> Result<&'static str> {
        Ok(match name {
            "version" | "documentation" | "skin" => "skip",
            "name" => {
                self.sk.name = toks[1..].join(" ");
                "skip"
            }
            "units" => "units",
            "root" => "root",
            "bonedata" => "bonedata",
            "hierarchy" => {
                self.seen_hierarchy = true;
                "hierarchy"
            }
            _ => {
                return Err(err(
                    self.file,
                    ln,
                    "a known section (:units, :root, :bonedata, :hierarchy...)",
                ))
            }
        })
    }

    /// A `:units` line: `length`, `mass`, `angle` (vendor extras ignored).
    fn units(&mut self, ln: usize, toks: &[&str]) -> Result<()> {
        let value = || number(self.file, ln, toks.get(1).copied().unwrap_or(""));
        match toks[0] {
            "length" => self.sk.length_unit = value()?,
            "mass" => self.sk.mass_unit = value()?,
            "angle" => self.sk.degrees = toks.get(1).is_some_and(|u| u.starts_with("deg")),
            _ => {}
        }
        Ok(())
    }

    /// A `:root` line: `order`, `axis`, `position` or `orientation`.
    fn root(&mut self, ln: usize, toks: &[&str]) -> Result<()> {
        let file = self.file;
        match toks[0] {
            "order" => {
                self.sk.root_order =
                    toks[1..].iter().map(|t| dof(file, ln, t)).collect::<Result<_>>()?
            }
            "axis" => {
                let order = toks.get(1).copied().unwrap_or("");
                self.sk.root_axis = EulerSequence::parse(&order.to_ascii_lowercase())
                    .map_err(|_| err(file, ln, "a root axis order such as XYZ"))?;
            }
            "position" | "orientation" => {
                if toks.len() != 4 {
                    return Err(err(file, ln, format!("three numbers after {}", toks[0])));
                }
                let v = three(file, ln, &toks[1..4])?;
                if toks[0] == "position" {
                    self.sk.root_position = DVec3::from_array(v);
                } else {
                    self.root_orientation = (v, ln);
                }
            }
            _ => return Err(err(file, ln, "order, axis, position or orientation in :root")),
        }
        Ok(())
    }

    /// A `:bonedata` line: limits continued from the line before, `begin`, `end`, or a
    /// keyword of the current bone.
    fn bonedata(&mut self, ln: usize, line: &str, toks: &[&str]) -> Result<()> {
        if let Some((n, vals)) = self.pending_limits.as_mut() {
            if !toks[0].starts_with('(') {
                return Err(err(self.file, ln, format!("{n} limits (lo hi), one per dof")));
            }
            for t in line.replace(['(', ')'], " ").split_whitespace() {
                vals.push(limit(self.file, ln, t)?);
            }
            if vals.len() >= 2 * *n {
                let (_, vals) = self.pending_limits.take().expect("checked");
                let bone = &mut self.current.as_mut().expect("inside a bone").0;
                bone.limits = vals.chunks(2).map(|c| (c[0], c[1])).collect();
            }
            return Ok(());
        }
        match toks[0] {
            "begin" => {
                let bone = Bone {
                    name: String::new(),
                    parent: None,
                    direction: DVec3::ZERO,
                    length: f64::NAN, // required: checked once the bones are read
                    axis: DQuat::IDENTITY,
                    axis_as_read: ([0.0; 3], String::new()),
                    dofs: vec![],
                    limits: vec![],
                };
                self.current = Some((bone, [0.0; 3], "XYZ".into(), ln));
            }
            "end" => {
                let b =
                    self.current.take().ok_or_else(|| err(self.file, ln, "begin before end"))?;
                if b.0.name.is_empty() {
                    return Err(err(self.file, ln, "a name in every bone"));
                }
                self.bones.push(b);
            }
            key => self.bone_keyword(ln, line, key, toks)?,
        }
        Ok(())
    }

    /// A keyword line inside `begin` … `end`.
    fn bone_keyword(&mut self, ln: usize, line: &str, key: &str, toks: &[&str]) -> Result<()> {
        let file = self.file;
        let (bone, angles, order, _) =
            self.current.as_mut().ok_or_else(|| err(file, ln, "begin before bone data"))?;
        match key {
            "id" | "bodymass" | "cofmass" => {}
            "name" => {
                bone.name = toks.get(1).ok_or_else(|| err(file, ln, "a bone name"))?.to_string()
            }
            "direction" => {
                if toks.len() != 4 {
                    return Err(err(file, ln, "three numbers after direction"));
                }
                bone.direction = DVec3::from_array(three(file, ln, &toks[1..4])?);
            }
            "length" => bone.length = number(file, ln, toks.get(1).copied().unwrap_or(""))?,
            "axis" => {
                if toks.len() != 5 {
                    return Err(err(file, ln, "three angles and an order after axis"));
                }
                *angles = three(file, ln, &toks[1..4])?;
                *order = toks[4].to_string();
            }
            "dof" => {
                bone.dofs = toks[1..].iter().map(|t| dof(file, ln, t)).collect::<Result<_>>()?
            }
            "limits" => {
                let n = bone.dofs.len();
                let mut vals = Vec::new();
                for t in line["limits".len()..].replace(['(', ')'], " ").split_whitespace() {
                    vals.push(limit(file, ln, t)?);
                }
                if vals.len() >= 2 * n {
                    bone.limits = vals.chunks(2).map(|c| (c[0], c[1])).collect();
                } else {
                    self.pending_limits = Some((n, vals));
                }
            }
            _ => {
                return Err(err(
                    file,
                    ln,
                    "a bone keyword (id, name, direction, length, axis, dof, limits)",
                ))
            }
        }
        Ok(())
    }

    /// A `:hierarchy` line: a parent and its children (`begin` / `end` ignored).
    fn hierarchy(&mut self, ln: usize, toks: &[&str]) {
        if let [parent, kids @ ..] = toks {
            if !matches!(*parent, "begin" | "end") {
                let kids = kids.iter().map(|s| s.to_string()).collect();
                self.children.push((ln, parent.to_string(), kids));
            }
        }
    }

    /// After the last line (`last`): check the file is complete, convert the root
    /// orientation and put the bones in hierarchy order.
    fn finish(mut self, last: usize) -> Result<Skeleton> {
        let file = self.file;
        if self.current.is_some() || self.pending_limits.is_some() {
            return Err(err(file, last, "end of the last bone (file truncated?)"));
        }
        if !self.seen_hierarchy {
            return Err(err(file, last, "a :hierarchy section (file truncated?)"));
        }
        let scale = self.angle_scale();
        let (o, oln) = self.root_orientation;
        let [i, j, k] = self.sk.root_axis.axes;
        self.sk.root_orientation_as_read = o;
        // The root axis order applies extrinsically like the bones' axes.
        self.sk.root_orientation = self
            .sk
            .root_axis
            .to_quat(&[o[i] * scale, o[j] * scale, o[k] * scale])
            .map_err(|_| err(file, oln, "a finite root orientation"))?;
        let parent_of = self.parents()?;
        let order = self.hierarchy_order(&parent_of)?;
        let new_index: HashMap<usize, usize> =
            order.iter().enumerate().map(|(new, &old)| (old, new)).collect();
        for &old in &order {
            let parent = parent_of[old].flatten().map(|p| new_index[&p]);
            let bone = self.finish_bone(old, parent, scale)?;
            self.sk.bones.push(bone);
        }
        Ok(self.sk)
    }

    /// Radians per file angle unit.
    fn angle_scale(&self) -> f64 {
        if self.sk.degrees {
            std::f64::consts::PI / 180.0
        } else {
            1.0
        }
    }

    /// Each bone's parent from `:hierarchy`: `None` if not listed, `Some(None)` under the
    /// root, `Some(Some(k))` under bone `k` (indices in file order).
    fn parents(&self) -> Result<Vec<Option<Option<usize>>>> {
        let file = self.file;
        let mut index: HashMap<&str, usize> = HashMap::new();
        for (k, b) in self.bones.iter().enumerate() {
            if index.insert(&b.0.name, k).is_some() {
                let why = format!("a unique bone name, {:?} is repeated", b.0.name);
                return Err(err(file, b.3, why));
            }
        }
        let mut parent_of = vec![None; self.bones.len()];
        for (ln, parent, kids) in &self.children {
            let known =
                |name: &str| index.get(name).copied().ok_or_else(|| err(file, *ln, "a known bone"));
            let p = if parent == "root" { None } else { Some(known(parent)?) };
            for kid in kids {
                let c = known(kid)?;
                if parent_of[c].is_some() {
                    return Err(err(file, *ln, format!("one parent per bone, {kid:?} has two")));
                }
                parent_of[c] = Some(p);
            }
        }
        Ok(parent_of)
    }

    /// Bone indices (file order) parents first, breadth first from the root.
    ///
    /// # Errors
    /// A bone missing from the hierarchy or in a cycle of it.
    fn hierarchy_order(&self, parent_of: &[Option<Option<usize>>]) -> Result<Vec<usize>> {
        let n = self.bones.len();
        let mut order: Vec<usize> = Vec::with_capacity(n);
        let mut placed = vec![false; n];
        let mut frontier: Vec<Option<usize>> = vec![None];
        while let Some(p) = frontier.pop() {
            for c in 0..n {
                if !placed[c] && parent_of[c] == Some(p) {
                    placed[c] = true;
                    order.push(c);
                    frontier.insert(0, Some(c));
                }
            }
        }
        if let Some(c) = (0..n).find(|&c| !placed[c]) {
            let why = if parent_of[c].is_none() {
                "is missing from :hierarchy"
            } else {
                "is in a cycle of the hierarchy"
            };
            let (bone, ln) = (&self.bones[c].0, self.bones[c].3);
            return Err(err(
                self.file,
                ln,
                format!("a tree of bones under root; {:?} {why}", bone.name),
            ));
        }
        Ok(order)
    }

    /// Bone `old` (file order) checked and converted: its parent (hierarchy order), unit
    /// direction, axis rotation and rotation limits in radians.
    fn finish_bone(&self, old: usize, parent: Option<usize>, scale: f64) -> Result<Bone> {
        let file = self.file;
        let (mut bone, angles, ord, ln) = self.bones[old].clone();
        bone.parent = parent;
        // The Acclaim ASF format gives every bone a length (an explicit `length 0` is legal).
        if bone.length.is_nan() || bone.length < 0.0 {
            let what = if bone.length.is_nan() { "missing" } else { "negative" };
            return Err(err(file, ln, format!("a length >= 0 for bone {:?} ({what})", bone.name)));
        }
        // A bone of length 0 (exporters' `_dum` placeholders) may have no direction.
        let len = bone.direction.length();
        if len > 0.0 {
            bone.direction /= len;
        } else if bone.length != 0.0 {
            return Err(err(file, ln, format!("a non-zero direction for bone {:?}", bone.name)));
        }
        bone.axis = axis_rotation(file, ln, angles.map(|a| a * scale), &ord)?;
        bone.axis_as_read = (angles, ord);
        if !bone.limits.is_empty() && bone.limits.len() != bone.dofs.len() {
            return Err(err(file, ln, format!("one limit per dof for bone {:?}", bone.name)));
        }
        for (l, d) in bone.limits.iter_mut().zip(&bone.dofs) {
            if matches!(d, Dof::Rotation(_)) {
                *l = (l.0 * scale, l.1 * scale);
            }
        }
        Ok(bone)
    }
}

/// Parse an AMC motion for `skeleton`; `file` names it in errors. Rotations are converted to
/// radians when the skeleton's angles are in degrees.
///
/// # Errors
/// [`Error::Parse`]: an unknown bone, a wrong number of values, a bad number, a frame that
/// misses a bone with dofs, no frames.
pub fn parse_amc(text: &str, file: &str, skeleton: &Skeleton) -> Result<Motion> {
    let stride = skeleton.stride();
    let mut offsets: HashMap<&str, (usize, &[Dof])> = HashMap::new();
    offsets.insert("root", (0, &skeleton.root_order));
    let mut k = skeleton.root_order.len();
    for b in &skeleton.bones {
        offsets.insert(&b.name, (k, &b.dofs));
        k += b.dofs.len();
    }
    let scale = if skeleton.degrees { std::f64::consts::PI / 180.0 } else { 1.0 };
    let mut values: Vec<f64> = Vec::new();
    let mut frames = 0usize;
    let mut filled: Vec<bool> = Vec::new();
    let check_complete = |filled: &[bool], frame: usize, ln: usize| -> Result<()> {
        if let Some(missing) =
            offsets.iter().find(|(_, (off, dofs))| !dofs.is_empty() && !filled[*off])
        {
            return Err(err(file, ln, format!("values for {:?} in frame {frame}", missing.0)));
        }
        Ok(())
    };
    let all = lines(text);
    let mut last_line = 1;
    for &(ln, line) in &all {
        last_line = ln;
        if line.starts_with(':') {
            continue;
        }
        let toks: Vec<&str> = line.split_whitespace().collect();
        if toks.len() == 1 && toks[0].parse::<u64>().is_ok() {
            if frames > 0 {
                check_complete(&filled, frames, ln)?;
            }
            frames += 1;
            values.resize(frames * stride, 0.0);
            filled = vec![false; stride.max(1)];
            continue;
        }
        if frames == 0 {
            return Err(err(file, ln, "a frame number before bone values".to_string()));
        }
        let (off, dofs) = *offsets
            .get(toks[0])
            .ok_or_else(|| err(file, ln, "a bone of the skeleton".to_string()))?;
        if toks.len() - 1 != dofs.len() {
            return Err(err(
                file,
                ln,
                format!("{} values for {:?}, found {}", dofs.len(), toks[0], toks.len() - 1),
            ));
        }
        let base = (frames - 1) * stride + off;
        for (i, (t, d)) in toks[1..].iter().zip(dofs).enumerate() {
            let v = number(file, ln, t)?;
            values[base + i] = if matches!(d, Dof::Rotation(_)) { v * scale } else { v };
        }
        if !dofs.is_empty() {
            filled[off] = true;
        }
    }
    if frames == 0 {
        return Err(err(file, last_line, "at least one frame"));
    }
    check_complete(&filled, frames, last_line)?;
    Ok(Motion { values, stride, frames, frame_rate: super::CMU_FRAME_RATE })
}
