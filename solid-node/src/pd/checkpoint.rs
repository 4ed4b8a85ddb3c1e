//! Checkpoint encoding for the peridynamic node (`Solver::save_state` / `load_state`):
//! little-endian raw f64/u64 blocks with a length prefix each, read back with length checks
//! (a truncated or foreign blob is refused, never trusted), so a restart continues
//! bit-identically.
// Index loops over the 3 or 6 components of small tensors read closer to the formulas;
// `!(x > 0.0)` is deliberate: it also rejects NaN.
#![allow(
    clippy::needless_range_loop,
    clippy::neg_cmp_op_on_partial_ord,
    clippy::too_many_arguments
)]

/// Appends values to a checkpoint blob.
#[derive(Debug, Default)]
pub struct Writer {
    pub buf: Vec<u8>,
}

impl Writer {
    pub fn u64(&mut self, v: u64) {
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    pub fn f64(&mut self, v: f64) {
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    /// A length-prefixed block of f64.
    pub fn f64s(&mut self, v: impl ExactSizeIterator<Item = f64>) {
        self.u64(v.len() as u64);
        for x in v {
            self.f64(x);
        }
    }
    pub fn bytes(&mut self, v: &[u8]) {
        self.u64(v.len() as u64);
        self.buf.extend_from_slice(v);
    }
}

/// Reads a blob written by [`Writer`]; every read checks the remaining length.
#[derive(Debug)]
pub struct Reader<'a> {
    pub rest: &'a [u8],
}

impl<'a> Reader<'a> {
    pub fn new(b: &'a [u8]) -> Self {
        Reader { rest: b }
    }
    fn take(&mut self, n: usize) -> Result<&'a [u8], String> {
        if self.rest.len() < n {
            return Err(format!(
                "checkpoint truncated: need {n} bytes, {} left",
                self.rest.len()
            ));
        }
        let (a, b) = self.rest.split_at(n);
        self.rest = b;
        Ok(a)
    }
    pub fn u64(&mut self) -> Result<u64, String> {
        let a = self.take(8)?;
        let mut b = [0u8; 8];
        b.copy_from_slice(a);
        Ok(u64::from_le_bytes(b))
    }
    pub fn f64(&mut self) -> Result<f64, String> {
        Ok(f64::from_bits(self.u64()?))
    }
    /// A length-prefixed f64 block that must hold exactly `expect` values.
    pub fn f64s(&mut self, expect: usize, what: &str) -> Result<Vec<f64>, String> {
        let n = self.u64()? as usize;
        if n != expect {
            return Err(format!("checkpoint {what}: {n} values, expected {expect}"));
        }
        let a = self.take(8 * n)?;
        Ok(a.chunks_exact(8)
            .map(|c| {
                let mut b = [0u8; 8];
                b.copy_from_slice(c);
                f64::from_le_bytes(b)
            })
            .collect())
    }
    pub fn bytes(&mut self, expect: usize, what: &str) -> Result<&'a [u8], String> {
        let n = self.u64()? as usize;
        if n != expect {
            return Err(format!("checkpoint {what}: {n} bytes, expected {expect}"));
        }
        self.take(n)
    }
}

/// Flattens [x; 3] arrays.
pub fn flat3(v: &[[f64; 3]]) -> impl ExactSizeIterator<Item = f64> + '_ {
    let n = v.len();
    (0..3 * n).map(move |k| v[k / 3][k % 3])
}

/// Rebuilds [x; 3] arrays from a flat block.
pub fn unflat3(v: &[f64], out: &mut [[f64; 3]]) {
    for (o, c) in out.iter_mut().zip(v.chunks_exact(3)) {
        *o = [c[0], c[1], c[2]];
    }
}

/// J2 states as 13 numbers each (stress, back stress, ε̄ᵖ).
pub fn put_j2(w: &mut Writer, s: &[mechanics::j2::J2State]) {
    let n = s.len();
    w.f64s((0..13 * n).map(|k| {
        let st = &s[k / 13];
        match k % 13 {
            c @ 0..=5 => st.stress[c],
            c @ 6..=11 => st.back_stress[c - 6],
            _ => st.eq_plastic_strain,
        }
    }));
}

pub fn get_j2(
    r: &mut Reader,
    out: &mut [mechanics::j2::J2State],
    what: &str,
) -> Result<(), String> {
    let v = r.f64s(13 * out.len(), what)?;
    for (st, c) in out.iter_mut().zip(v.chunks_exact(13)) {
        st.stress.copy_from_slice(&c[0..6]);
        st.back_stress.copy_from_slice(&c[6..12]);
        st.eq_plastic_strain = c[12];
    }
    Ok(())
}
