//! Constraint files: a count M, then M records `m1 v1 m2 v2 lower upper` (0-based body and
//! vertex indices, bounds as fractions of the initial distance).

use super::limits::MAX_CONSTRAINTS;
use super::tokens::{RecordLayout, Tokens};
use super::{LoadError, Records};
use std::path::Path;

#[derive(Debug, Clone, PartialEq)]
pub struct ConstraintRecord {
    pub body1: usize,
    pub vertex1: usize,
    pub body2: usize,
    pub vertex2: usize,
    pub lower: f64,
    pub upper: f64,
    pub line: usize,
}

const CONSTRAINT_RECORD: RecordLayout = RecordLayout {
    name: "a constraint record",
    fields: &["m1", "v1", "m2", "v2", "lower", "upper"],
};

/// The records of constraint file `file` holding `text`. A scene file given as constraints is
/// said to be one.
pub fn parse_constraints(file: &Path, text: &str) -> Result<Records<ConstraintRecord>, LoadError> {
    read_constraints(file, text).map_err(|error| match super::scene_file::read_scene(file, text) {
        Ok(read) if !read.records.is_empty() => {
            error.noting("it reads as a scene file: give it as the scene")
        }
        _ => error,
    })
}

pub(super) fn read_constraints(
    file: &Path,
    text: &str,
) -> Result<Records<ConstraintRecord>, LoadError> {
    let mut tokens = Tokens::new(file, text);
    // A file with nothing in it (or comments only) holds no constraints: what a user who
    // empties the file beside a scene means.
    if tokens.peek().is_none() {
        return Ok(Records::default());
    }
    let count = tokens.count_records(
        "the number of constraints",
        &CONSTRAINT_RECORD,
        MAX_CONSTRAINTS,
    )?;
    let mut records = Vec::with_capacity(count);
    for _ in 0..count {
        let (body1, line) = tokens.index("the first body index")?;
        let (vertex1, _) = tokens.index("the first vertex index")?;
        let (body2, _) = tokens.index("the second body index")?;
        let (vertex2, _) = tokens.index("the second vertex index")?;
        let (lower, lower_line) = tokens.real("the lower bound")?;
        let (upper, _) = tokens.real("the upper bound")?;
        if lower < 0.0 || upper < lower {
            return Err(tokens.error(
                lower_line,
                format!(
                    "bounds must satisfy 0 <= lower <= upper, found {} and {}",
                    super::echoed(lower),
                    super::echoed(upper)
                ),
            ));
        }
        records.push(ConstraintRecord {
            body1,
            vertex1,
            body2,
            vertex2,
            lower,
            upper,
            line,
        });
    }
    tokens.expect_end(&super::counted(count as u64, "constraint", "constraints"))?;
    Ok(Records {
        records,
        layout_warning: tokens.layout_warning(),
    })
}
