//! msh 4.1 (ASCII and binary) through mshio, plus `$PhysicalNames`, which mshio skips (the
//! section is ASCII even in binary files).
//!
//! Physical tags come from the entity of each element block (`$Entities`). When node tags are
//! dense, mshio drops them (`node_tags` is `None`): they are then `min_node_tag` plus the
//! running index in file order, which is how gmsh writes dense tags.
use std::collections::BTreeMap;

use flem_core::{FlemError, Result};
use mshio::MshFile;

use super::cursor::{shorten, Cursor};
use super::gmsh::{read_physical_names, MshContent, MshElement};
use super::no_panic;

/// Reads the `$PhysicalNames` section(s), skipping every other section byte-wise.
fn physical_names(src: &str, bytes: &[u8]) -> Result<BTreeMap<(i32, i32), String>> {
    let mut c = Cursor::new(src, bytes);
    let mut names = BTreeMap::new();
    loop {
        c.skip_ws();
        if c.at_end() {
            return Ok(names);
        }
        let l = c.line().unwrap_or_default();
        let name = std::str::from_utf8(l).ok().and_then(|s| s.trim().strip_prefix('$'));
        match name {
            Some("PhysicalNames") => read_physical_names(&mut c, &mut names)?,
            Some(n) if !n.is_empty() && n.bytes().all(|b| b.is_ascii_alphanumeric()) => c.skip_section(n)?,
            _ => {
                let shown = String::from_utf8_lossy(&l[..l.len().min(40)]).into_owned();
                return Err(c.err(format!("expected a section header ($Name), found \"{}\"", shorten(&shown))));
            }
        }
    }
}

/// The sections of a msh file: (name, offset of the `$Name` line, offset after its `$EndName`
/// line). `physical_names` has already checked that every section ends.
fn sections(src: &str, bytes: &[u8]) -> Vec<(String, usize, usize)> {
    let mut c = Cursor::new(src, bytes);
    let mut out = Vec::new();
    loop {
        c.skip_ws();
        if c.at_end() {
            return out;
        }
        let start = c.pos;
        let l = c.line().unwrap_or_default();
        let Some(name) = std::str::from_utf8(l).ok().and_then(|s| s.trim().strip_prefix('$')).filter(|n| !n.is_empty() && n.bytes().all(|b| b.is_ascii_alphanumeric())) else {
            return out;
        };
        let name = name.to_string();
        if c.skip_section(&name).is_err() {
            return out;
        }
        out.push((name, start, c.pos));
    }
}

/// 1-based line of the byte offset `o`.
fn line_of(bytes: &[u8], o: usize) -> usize {
    1 + bytes[..o.min(bytes.len())].iter().filter(|&&c| c == b'\n').count()
}

/// Where mshio failed: "section $Name (lines a-b)", the first section whose prefix of the file
/// mshio refuses (it parses the sections one after the other, each on its own, so a section
/// that reads too far is still the one named), and "line n" of the failing input where mshio
/// gives it (its nom errors carry no position: "Unknown error occurred").
fn failing_place(src: &str, bytes: &[u8], at: Option<usize>) -> Option<String> {
    let secs = sections(src, bytes);
    let line = at.map(|o| format!("line {}", line_of(bytes, o)));
    for (n, a, b) in &secs {
        let prefix = &bytes[..*b];
        let ok = no_panic("the msh 4.1 parser (mshio)", || mshio::parse_msh_bytes(prefix).is_ok()).unwrap_or(false);
        if !ok {
            let s = format!("section ${n} (lines {}-{})", line_of(bytes, *a), line_of(bytes, b.saturating_sub(1)));
            return Some(match line {
                Some(l) => format!("{s}, {l}"),
                None => s,
            });
        }
    }
    line
}

/// Parses a whole msh 4.1 file.
pub(crate) fn parse(src: &str, bytes: &[u8]) -> Result<MshContent> {
    let names = physical_names(src, bytes)?;
    let parsed = no_panic("the msh 4.1 parser (mshio)", || {
        // mshio's Display appends a hex dump of the rest of the file (kilobytes): keep what
        // precedes it and name the section and line where the failing input starts instead.
        mshio::parse_msh_bytes(bytes).map_err(|e| {
            let s = e.to_string().split_whitespace().collect::<Vec<_>>().join(" ");
            let s = match s.find(" Hex dump of the file at the error location:") {
                Some(i) => s[..i].trim_end().to_string(),
                None => s,
            };
            // The failing input is a sub-slice of `bytes`: its start gives the offset.
            let at = e.filtered_backtrace().first().map(|(rest, _)| (rest.as_ptr() as usize).wrapping_sub(bytes.as_ptr() as usize)).filter(|&o| o <= bytes.len());
            (s, at)
        })
    });
    let msh: MshFile<u64, i32, f64> = match parsed {
        Ok(Ok(m)) => m,
        Ok(Err((s, at))) => {
            // "Unknown error occurred" is all mshio says when only its nom parsers failed.
            let s = if s.starts_with("Unknown error") { "its content does not follow the msh 4.1 format (mshio gives no detail)".to_string() } else { s };
            let place = failing_place(src, bytes, at);
            return Err(FlemError::mesh(src, format!("cannot parse the msh 4.1 file: {}{s}", place.map(|p| format!("{p}: ")).unwrap_or_default())));
        }
        Err(e) => return Err(FlemError::mesh(src, format!("cannot parse the msh 4.1 file: {e}"))),
    };
    let mut out = MshContent { names, ..Default::default() };
    let data = msh.data;
    if let Some(nodes) = &data.nodes {
        let mut next = nodes.min_node_tag;
        for block in &nodes.node_blocks {
            let mut tags = vec![None; block.nodes.len()];
            match &block.node_tags {
                Some(map) => {
                    for (&tag, &k) in map {
                        match tags.get_mut(k) {
                            Some(slot) => *slot = Some(tag),
                            None => return Err(FlemError::mesh(src, format!("node tag {tag} points outside its node block"))),
                        }
                    }
                }
                None => {
                    for slot in tags.iter_mut() {
                        *slot = Some(next);
                        next = next.saturating_add(1);
                    }
                }
            }
            for (node, tag) in block.nodes.iter().zip(tags) {
                let Some(tag) = tag else {
                    return Err(FlemError::mesh(src, format!("a node of the block of entity (dimension {}, tag {}) has no tag (duplicate tags?)", block.entity_dim, block.entity_tag)));
                };
                out.nodes.push((tag, [node.x, node.y, node.z]));
            }
        }
    }
    let mut phys: BTreeMap<(i32, i32), Vec<i32>> = BTreeMap::new();
    if let Some(ent) = &data.entities {
        for p in &ent.points {
            phys.insert((0, p.tag), p.physical_tags.clone());
        }
        for e in &ent.curves {
            phys.insert((1, e.tag), e.physical_tags.clone());
        }
        for e in &ent.surfaces {
            phys.insert((2, e.tag), e.physical_tags.clone());
        }
        for e in &ent.volumes {
            phys.insert((3, e.tag), e.physical_tags.clone());
        }
    }
    if let Some(elements) = &data.elements {
        for block in &elements.element_blocks {
            let key = (block.entity_dim, block.entity_tag);
            let tags = match (&data.entities, phys.get(&key)) {
                (None, _) => Vec::new(),
                (Some(_), Some(t)) => t.clone(),
                (Some(_), None) => {
                    return Err(FlemError::mesh(src, format!("an element block refers to entity (dimension {}, tag {}), which is not in $Entities", key.0, key.1)));
                }
            };
            let ty = block.element_type as i32;
            for e in &block.elements {
                out.elements.push(MshElement { id: e.element_tag, ty, phys: tags.clone(), nodes: e.nodes.clone() });
            }
        }
    }
    Ok(out)
}
