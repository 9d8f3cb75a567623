//! msh 2.2 reader (ASCII and binary); mshio reads only 4.1.
//!
//! Layout (gmsh manual, "MSH file format version 2"): `$MeshFormat` (binary files add the int
//! 1 to tell the byte order), optional `$PhysicalNames`, `$Nodes` (`n`, then `id x y z`),
//! `$Elements` (`n`, then `id type ntags tags... nodes...`; the first tag is the physical
//! group, 0 for none). Binary elements come in blocks: `type count ntags` as 3 ints, then per
//! element `id tags... nodes...` as ints. Other sections are skipped.
use flem_core::Result;

use super::cursor::{parse_tok, shorten, Cursor};
use super::gmsh::{element_type, read_physical_names, MshContent, MshElement};

/// Byte order of a binary file.
#[derive(Copy, Clone)]
enum Order {
    Little,
    Big,
}

fn int(o: Order, b: &[u8]) -> i32 {
    let a = [b[0], b[1], b[2], b[3]];
    match o {
        Order::Little => i32::from_le_bytes(a),
        Order::Big => i32::from_be_bytes(a),
    }
}

fn double(o: Order, b: &[u8]) -> f64 {
    let mut a = [0u8; 8];
    a.copy_from_slice(&b[..8]);
    match o {
        Order::Little => f64::from_le_bytes(a),
        Order::Big => f64::from_be_bytes(a),
    }
}

/// Parses everything after the format line.
pub(crate) fn parse(mut c: Cursor, binary: bool) -> Result<MshContent> {
    let mut order = None;
    if binary {
        let one = c.take(4, "the byte-order mark of $MeshFormat")?;
        order = Some(match (i32::from_le_bytes([one[0], one[1], one[2], one[3]]), i32::from_be_bytes([one[0], one[1], one[2], one[3]])) {
            (1, _) => Order::Little,
            (_, 1) => Order::Big,
            _ => return Err(c.err("the byte-order mark of a binary file must be the integer 1")),
        });
    }
    c.expect_end("MeshFormat")?;
    let mut out = MshContent::default();
    loop {
        c.skip_ws();
        if c.at_end() {
            break;
        }
        let l = c.text_line("a section header")?;
        let Some(name) = l.strip_prefix('$') else {
            return Err(c.err(format!("expected a section header ($Name), found \"{}\"", shorten(l))));
        };
        match name {
            "PhysicalNames" => read_physical_names(&mut c, &mut out.names)?,
            "Nodes" => match order {
                None => nodes_ascii(&mut c, &mut out)?,
                Some(o) => nodes_binary(&mut c, o, &mut out)?,
            },
            "Elements" => match order {
                None => elements_ascii(&mut c, &mut out)?,
                Some(o) => elements_binary(&mut c, o, &mut out)?,
            },
            _ => c.skip_section(name)?,
        }
    }
    Ok(out)
}

fn count(c: &mut Cursor, what: &str) -> Result<usize> {
    let l = c.count_line()?;
    parse_tok(c, Some(l), what)
}

fn nodes_ascii(c: &mut Cursor, out: &mut MshContent) -> Result<()> {
    let n = count(c, "the number of nodes")?;
    for _ in 0..n {
        let l = c.text_line("a node line (id x y z)")?;
        let mut t = l.split_whitespace();
        let id: u64 = parse_tok(c, t.next(), "the node id")?;
        let x: f64 = parse_tok(c, t.next(), "the node's x")?;
        let y: f64 = parse_tok(c, t.next(), "the node's y")?;
        let z: f64 = parse_tok(c, t.next(), "the node's z")?;
        out.nodes.push((id, [x, y, z]));
    }
    c.expect_end("Nodes")
}

fn nodes_binary(c: &mut Cursor, o: Order, out: &mut MshContent) -> Result<()> {
    let n = count(c, "the number of nodes")?;
    for k in 0..n {
        let b = c.take(28, &format!("node {} of {n}", k + 1))?;
        let id = int(o, b);
        if id < 0 {
            return Err(c.err(format!("node {} of {n} has a negative id {id}", k + 1)));
        }
        out.nodes.push((id as u64, [double(o, &b[4..]), double(o, &b[12..]), double(o, &b[20..])]));
    }
    c.expect_end("Nodes")
}

fn elements_ascii(c: &mut Cursor, out: &mut MshContent) -> Result<()> {
    let n = count(c, "the number of elements")?;
    for _ in 0..n {
        let l = c.text_line("an element line (id type ntags tags... nodes...)")?;
        let mut t = l.split_whitespace();
        let id: u64 = parse_tok(c, t.next(), "the element id")?;
        let ty: i32 = parse_tok(c, t.next(), &format!("the type of element {id}"))?;
        let ntags: usize = parse_tok(c, t.next(), &format!("the tag count of element {id}"))?;
        let mut tags = Vec::new();
        for _ in 0..ntags {
            tags.push(parse_tok::<i32>(c, t.next(), &format!("a tag of element {id}"))?);
        }
        let mut nodes = Vec::new();
        for tok in t {
            nodes.push(parse_tok::<u64>(c, Some(tok), &format!("a node of element {id}"))?);
        }
        out.elements.push(MshElement { id, ty, phys: tags.first().copied().into_iter().collect(), nodes });
    }
    c.expect_end("Elements")
}

fn elements_binary(c: &mut Cursor, o: Order, out: &mut MshContent) -> Result<()> {
    let n = count(c, "the number of elements")?;
    let mut read = 0usize;
    while read < n {
        let h = c.take(12, "an element block header (type count ntags)")?;
        let (ty, m, ntags) = (int(o, h), int(o, &h[4..]), int(o, &h[8..]));
        let Some((k, _)) = element_type(ty) else {
            return Err(c.err(format!("element type {ty} is unknown to FLEM (a binary file cannot be read past it)")));
        };
        if m <= 0 || m as usize > n - read || !(0..=64).contains(&ntags) {
            return Err(c.err(format!("bad element block header: type {ty}, {m} elements, {ntags} tags ({} of {n} elements left)", n - read)));
        }
        let ntags = ntags as usize;
        for _ in 0..m {
            let b = c.take(4 * (1 + ntags + k), &format!("an element of type {ty}"))?;
            let v: Vec<i32> = b.chunks_exact(4).map(|w| int(o, w)).collect();
            let id = v[0];
            if id < 0 || v[1 + ntags..].iter().any(|&x| x < 0) {
                return Err(c.err(format!("element {id} has a negative id or node")));
            }
            let phys = v[1..1 + ntags].first().copied().into_iter().collect();
            out.elements.push(MshElement { id: id as u64, ty, phys, nodes: v[1 + ntags..].iter().map(|&x| x as u64).collect() });
        }
        read += m as usize;
    }
    c.expect_end("Elements")
}
