//! Where in a VTK file vtkio failed: vtkio's errors carry no position (a legacy parse error is a
//! bare nom error kind, an XML one a deserializer message), so when it refuses a file this
//! scanner, run only on that failure path, looks for the first damage it can name: a line and
//! the section, piece and data array being read (a cut file, a tag closed wrongly, a value
//! that is not a number, a count that does not match). `None` when it finds nothing (then only
//! vtkio's message is given).
//!
//! Why a hand scanner and not quick-xml (vtkio's own XML reader, in the build through vtkio):
//! what is reported is the context of damage (the open section, piece and `Name`d data array,
//! the counts of the piece, the position of the first bad token of an array body), which a
//! reader of well-formed XML does not keep, and quick-xml would add a direct dependency pinned
//! to the version vtkio's release candidate uses. The tag walk itself (comments, declarations,
//! start/end tags, `key="value"`) is the part quick-xml could replace (about 50 lines) if that
//! dependency is taken on later. Legacy files have no crate to parse them with positions.

/// 1-based line of byte offset `at`.
fn line_of(text: &str, at: usize) -> usize {
    text.as_bytes()[..at.min(text.len())].iter().filter(|&&b| b == b'\n').count() + 1
}

/// An attribute of a start tag's text (`key="value"`).
fn attr<'a>(tag: &'a str, key: &str) -> Option<&'a str> {
    let mut rest = tag;
    while let Some(i) = rest.find(key) {
        let before = rest[..i].chars().last();
        let after = &rest[i + key.len()..];
        if before.is_some_and(char::is_whitespace) {
            if let Some(v) = after.trim_start().strip_prefix('=').map(str::trim_start).and_then(|v| v.strip_prefix('"')) {
                return v.split('"').next();
            }
        }
        rest = after;
    }
    None
}

/// The position hint for an XML (.vtu) file.
pub(crate) fn locate_xml(bytes: &[u8]) -> Option<String> {
    let text = String::from_utf8_lossy(bytes);
    let text = text.as_ref();
    // Open elements: (name, line, Name attribute, piece index).
    let mut stack: Vec<(String, usize, Option<String>)> = Vec::new();
    let mut piece: Option<usize> = None;
    let mut n_pieces = 0usize;
    let mut counts: (Option<u64>, Option<u64>) = (None, None);
    let mut i = 0usize;
    let ctx = |stack: &[(String, usize, Option<String>)], piece: Option<usize>| -> String {
        let mut s = String::new();
        if let Some((name, line, n)) = stack.iter().rev().find(|e| e.0 == "DataArray") {
            s = format!(" in <{name} Name=\"{}\"> (opened at line {line})", n.as_deref().unwrap_or("?"));
            if let Some(sec) = stack.iter().rev().find(|e| matches!(e.0.as_str(), "Points" | "Cells" | "CellData" | "PointData" | "FieldData")) {
                s.push_str(&format!(" of <{}>", sec.0));
            }
        }
        if let Some(p) = piece {
            s.push_str(&format!(" of piece {p}"));
        }
        s
    };
    while let Some(off) = text[i..].find('<') {
        let start = i + off;
        let rest = &text[start..];
        if rest.starts_with("<!--") {
            let Some(e) = rest.find("-->") else { return Some(format!("line {}: the file ends inside a comment: it is cut short", line_of(text, start))) };
            i = start + e + 3;
            continue;
        }
        if rest.starts_with("<?") || rest.starts_with("<!") {
            let Some(e) = rest.find('>') else { return Some(format!("line {}: the file ends inside a declaration: it is cut short", line_of(text, start))) };
            i = start + e + 1;
            continue;
        }
        let Some(e) = rest.find('>') else {
            return Some(format!("line {}: the file ends inside a tag{}: it is cut short", line_of(text, start), ctx(&stack, piece)));
        };
        let tag = &rest[1..e];
        let line = line_of(text, start);
        i = start + e + 1;
        if let Some(name) = tag.strip_prefix('/') {
            let name = name.trim();
            match stack.pop() {
                Some((open, _, _)) if open == name => {}
                Some((open, at, _)) => return Some(format!("line {line}: </{name}> closes <{open}> opened at line {at}{}", ctx(&stack, piece))),
                None => return Some(format!("line {line}: </{name}> closes nothing")),
            }
            if name == "Piece" {
                piece = None;
            }
            continue;
        }
        let name = tag.split(|c: char| c.is_whitespace() || c == '/').next().unwrap_or("").to_string();
        if name == "AppendedData" {
            // Raw bytes follow: nothing more to check by text.
            return None;
        }
        if name == "Piece" {
            piece = Some(n_pieces);
            n_pieces += 1;
            let num = |k| attr(tag, k).and_then(|v| v.trim().parse::<u64>().ok());
            counts = (num("NumberOfPoints"), num("NumberOfCells"));
        }
        if tag.ends_with('/') {
            continue;
        }
        let array_name = attr(tag, "Name").map(str::to_string);
        stack.push((name.clone(), line, array_name.clone()));
        if name != "DataArray" {
            continue;
        }
        // The array's content runs to the next '<'.
        let body_end = text[i..].find('<').map_or(text.len(), |k| i + k);
        let body = &text[i..body_end];
        let format = attr(tag, "format").unwrap_or("ascii");
        let ty = attr(tag, "type").unwrap_or("Float64");
        let here = ctx(&stack, piece);
        if body_end == text.len() {
            return Some(format!("line {}: the file ends{here}: it is cut short", line_of(text, text.len())));
        }
        if format == "ascii" {
            let mut n = 0u64;
            let mut pos = i;
            for tok in body.split_ascii_whitespace() {
                let at = pos + text[pos..].find(tok).unwrap_or(0);
                pos = at + tok.len();
                let ok = if ty.starts_with("Float") { tok.parse::<f64>().is_ok() } else { tok.parse::<i64>().is_ok() || tok.parse::<u64>().is_ok() };
                if !ok {
                    return Some(format!("line {}: \"{}\"{here} is not a{} number", line_of(text, at), tok.escape_debug(), if ty.starts_with("Float") { "" } else { " whole" }));
                }
                n += 1;
            }
            let comps = attr(tag, "NumberOfComponents").and_then(|v| v.trim().parse::<u64>().ok()).unwrap_or(1).max(1);
            let sec = stack.iter().rev().nth(1).map(|e| e.0.as_str()).unwrap_or("");
            let want = match (sec, array_name.as_deref()) {
                ("Points", _) => counts.0.map(|p| (p.saturating_mul(comps), "NumberOfPoints")),
                ("PointData", _) => counts.0.map(|p| (p.saturating_mul(comps), "NumberOfPoints")),
                ("Cells", Some("offsets" | "types")) | ("CellData", _) => counts.1.map(|c| (c.saturating_mul(comps), "NumberOfCells")),
                _ => None,
            };
            if let Some((w, what)) = want {
                if n != w {
                    return Some(format!("line {line}: {n} values{here}, but the piece's {what} and NumberOfComponents = {comps} make {w}"));
                }
            }
        } else if format == "binary" {
            if let Some(k) = body.find(|c: char| !(c.is_ascii_alphanumeric() || c == '+' || c == '/' || c == '=' || c.is_ascii_whitespace())) {
                return Some(format!("line {}: a character that is not base64{here}", line_of(text, i + k)));
            }
        }
    }
    if let Some((name, at, _)) = stack.last() {
        return Some(format!("line {}: the file ends with <{name}> (opened at line {at}){} still open: it is cut short", line_of(text, text.len()), ctx(&stack, piece)));
    }
    None
}

/// The position hint for a legacy (.vtk) file: for ASCII files, the first value that is not a
/// number or the section the file ends in, with its line; binary files only get the section.
pub(crate) fn locate_legacy(bytes: &[u8]) -> Option<String> {
    // The header: 4 lines (version, title, ASCII/BINARY, DATASET ...).
    let mut lines = bytes.split(|&b| b == b'\n');
    let head: Vec<&[u8]> = lines.by_ref().take(4).collect();
    if head.len() < 4 {
        return Some(format!("line {}: the file ends in its 4-line header (version, title, ASCII/BINARY, DATASET): it is cut short", head.len().max(1)));
    }
    let fmt = String::from_utf8_lossy(head[2]).trim().to_ascii_uppercase();
    if fmt != "ASCII" && fmt != "BINARY" {
        return Some(format!("line 3: \"{}\" where ASCII or BINARY is expected", String::from_utf8_lossy(head[2]).trim().escape_debug()));
    }
    if !String::from_utf8_lossy(head[3]).trim().to_ascii_uppercase().starts_with("DATASET") {
        return Some(format!("line 4: \"{}\" where DATASET UNSTRUCTURED_GRID is expected", String::from_utf8_lossy(head[3]).trim().escape_debug()));
    }
    if fmt == "BINARY" {
        return None;
    }
    let text = String::from_utf8_lossy(bytes);
    // Tokens with their line numbers, after the header.
    let toks: Vec<(usize, &str)> = text.lines().enumerate().skip(4).flat_map(|(l, s)| s.split_ascii_whitespace().map(move |t| (l + 1, t))).collect();
    let last_line = text.lines().count();
    let num = |k: usize| toks.get(k).and_then(|t| t.1.parse::<u64>().ok());
    let mut k = 0usize;
    let mut n_data = 0u64;
    let mut last: Option<(&str, usize)> = None;
    // Checks `count` numbers from token k for section `what` (opened at `line`).
    let values = |k: usize, count: u64, what: &str, line: usize, whole: bool| -> Result<usize, String> {
        for j in 0..count as usize {
            match toks.get(k + j) {
                None => return Err(format!("line {last_line}: the file ends in {what} (line {line}) after {j} of its {count} values: it is cut short")),
                Some((l, t)) => {
                    let ok = if whole { t.parse::<i64>().is_ok() } else { t.parse::<f64>().is_ok() };
                    if !ok {
                        let of = if count == u64::MAX { String::from("more than 2^64 declared") } else { count.to_string() };
                        return Err(format!("line {l}: \"{}\" in {what} (line {line}), value {} of {of}, is not a{} number", t.escape_debug(), j + 1, if whole { " whole" } else { "" }));
                    }
                }
            }
        }
        Ok(k.saturating_add(count as usize))
    };
    while k < toks.len() {
        let (line, kw) = toks[k];
        let kw_up = kw.to_ascii_uppercase();
        let res = match kw_up.as_str() {
            "POINTS" => num(k + 1).map(|n| values(k + 3, n.saturating_mul(3), "POINTS", line, false)),
            // Version 5 files: CELLS n m, then OFFSETS and CONNECTIVITY arrays (not checked here).
            "CELLS" if toks.get(k + 3).is_some_and(|t| t.1.parse::<i64>().is_err()) => return None,
            "CELLS" => num(k + 1).zip(num(k + 2)).map(|(n, size)| {
                let end = values(k + 3, size, "CELLS", line, true)?;
                // n groups "count i1 .. icount" must fill exactly `size` values.
                // (Counts come from a damaged file: the walk stops at the section's end, and
                // sums saturate, so a count of 1e14 neither loops for days nor wraps.)
                let (mut j, mut used, mut cells) = (k + 3, 0u64, 0u64);
                while cells < n && j < end {
                    let c = toks.get(j).and_then(|t| t.1.parse::<u64>().ok()).unwrap_or(0);
                    used = used.saturating_add(c.saturating_add(1));
                    j = j.saturating_add((c as usize).saturating_add(1));
                    cells += 1;
                }
                if cells < n {
                    return Err(format!("line {line}: CELLS {n} {size}: its {size} values hold {cells} cells, not {n}"));
                }
                if used != size {
                    return Err(format!("line {line}: CELLS {n} {size}: its {n} cells take {used} values, not the {size} it declares"));
                }
                Ok(end)
            }),
            "CELL_TYPES" => num(k + 1).map(|n| values(k + 2, n, "CELL_TYPES", line, true)),
            "CELL_DATA" | "POINT_DATA" => num(k + 1).map(|n| {
                n_data = n;
                Ok(k + 2)
            }),
            "SCALARS" => {
                // SCALARS name type [ncomp], then LOOKUP_TABLE name.
                let name = toks.get(k + 1).map_or("?", |t| t.1);
                let mut j = k + 3;
                let mut comps = 1;
                if let Some(c) = num(j) {
                    comps = c;
                    j += 1;
                }
                if toks.get(j).is_some_and(|t| t.1.eq_ignore_ascii_case("LOOKUP_TABLE")) {
                    j += 2;
                }
                Some(values(j, n_data.saturating_mul(comps), &format!("SCALARS {name}"), line, false))
            }
            "VECTORS" | "NORMALS" => {
                let name = toks.get(k + 1).map_or("?", |t| t.1);
                Some(values(k + 3, n_data.saturating_mul(3), &format!("{kw_up} {name}"), line, false))
            }
            "FIELD" => num(k + 2).map(|arrays| {
                let mut j = k + 3;
                for _ in 0..arrays {
                    let Some((l, name)) = toks.get(j).copied() else { return Err(format!("line {last_line}: the file ends in FIELD (line {line}) before all its {arrays} arrays: it is cut short")) };
                    let (Some(c), Some(t)) = (num(j + 1), num(j + 2)) else { return Err(format!("line {l}: field array \"{}\" lacks its component and tuple counts", name.escape_debug())) };
                    j = values(j + 4, c.saturating_mul(t), &format!("field array {name}"), l, false)?;
                }
                Ok(j)
            }),
            _ if kw.parse::<f64>().is_ok() => {
                return Some(format!(
                    "line {line}: the number \"{kw}\" where a section keyword (CELL_TYPES, CELL_DATA, SCALARS...) is expected: the section before{} has more values than its counts say",
                    last.map_or(String::new(), |(w, l): (&str, usize)| format!(" ({w}, line {l})"))
                ))
            }
            _ => return None,
        };
        last = Some((kw, line));
        match res {
            Some(Ok(next)) => k = next,
            Some(Err(msg)) => return Some(msg),
            None => return Some(format!("line {line}: {kw} lacks its counts")),
        }
    }
    None
}
