//! Two byte layouts of one IDL struct, written by one description of its fields.
//!
//! DDS carries a struct as XCDR1 (each primitive aligned to its own size from the start of the
//! body, nested structs unpadded); Unitree's CRC runs over the C++ struct in memory (natural
//! alignment: a nested struct starts and ends on its largest member's alignment). The two
//! differ as soon as a struct nests one with a wider member after a narrow field (the Go2's
//! `motor_cmd[0].mode` is at 22 in CDR, 24 in memory), so a type describes its fields once
//! ([`IdlStruct`]) and the writer and reader apply the layout's rules. Hand-written rather than
//! serde + `cdr-encoding`: the C image needs the same field walk anyway, the Unitree types are
//! fixed-size (no strings, sequences or optionals), and the core stays free of DDS crates.
//! Reading never panics: a short input is an error.

/// Which layout a [`IdlWriter`] / [`IdlReader`] applies.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Layout {
    /// XCDR1 body (little endian; the 4-byte encapsulation header is not part of it).
    Cdr,
    /// The C struct in memory on a little-endian machine, natural alignment, padding zero.
    CStruct,
}

#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum LayoutError {
    #[error("input ends at byte {len}, field needs bytes up to {needed}")]
    Short { needed: usize, len: usize },
}

/// A struct of the IDL, field by field.
pub trait IdlStruct: Sized {
    /// Its largest member's alignment, bytes (what the C layout aligns it to).
    const ALIGN: usize;
    fn write(&self, w: &mut IdlWriter);
    fn read(r: &mut IdlReader) -> Result<Self, LayoutError>;
}

pub struct IdlWriter {
    layout: Layout,
    buf: Vec<u8>,
}

impl IdlWriter {
    pub fn new(layout: Layout) -> Self {
        IdlWriter {
            layout,
            buf: Vec::with_capacity(1200),
        }
    }

    fn align(&mut self, n: usize) {
        while !self.buf.len().is_multiple_of(n) {
            self.buf.push(0);
        }
    }

    pub fn u8(&mut self, v: u8) {
        self.buf.push(v);
    }
    pub fn u8s(&mut self, v: &[u8]) {
        self.buf.extend_from_slice(v);
    }
    pub fn u16(&mut self, v: u16) {
        self.align(2);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    pub fn i16(&mut self, v: i16) {
        self.u16(v as u16);
    }
    pub fn u32(&mut self, v: u32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    pub fn i32(&mut self, v: i32) {
        self.u32(v as u32);
    }
    pub fn f32(&mut self, v: f32) {
        self.u32(v.to_bits());
    }

    /// A nested struct: in memory it starts and ends on its alignment, in CDR it does not.
    pub fn nested<T: IdlStruct>(&mut self, v: &T) {
        if self.layout == Layout::CStruct {
            self.align(T::ALIGN);
        }
        v.write(self);
        if self.layout == Layout::CStruct {
            self.align(T::ALIGN);
        }
    }

    /// The bytes of a top-level struct (`sizeof` in C: padded to its alignment).
    pub fn finish<T: IdlStruct>(mut self) -> Vec<u8> {
        if self.layout == Layout::CStruct {
            self.align(T::ALIGN);
        }
        self.buf
    }
}

/// Writes `v` in `layout`.
pub fn to_bytes<T: IdlStruct>(v: &T, layout: Layout) -> Vec<u8> {
    let mut w = IdlWriter::new(layout);
    v.write(&mut w);
    w.finish::<T>()
}

pub struct IdlReader<'a> {
    layout: Layout,
    buf: &'a [u8],
    at: usize,
}

impl<'a> IdlReader<'a> {
    pub fn new(buf: &'a [u8], layout: Layout) -> Self {
        IdlReader { layout, buf, at: 0 }
    }

    /// Bytes consumed so far.
    pub fn position(&self) -> usize {
        self.at
    }

    fn align(&mut self, n: usize) {
        self.at = self.at.div_ceil(n) * n;
    }

    fn take<const N: usize>(&mut self) -> Result<[u8; N], LayoutError> {
        let end = self.at + N;
        let got = self.buf.get(self.at..end).ok_or(LayoutError::Short {
            needed: end,
            len: self.buf.len(),
        })?;
        self.at = end;
        Ok(got.try_into().expect("slice of N bytes"))
    }

    pub fn u8(&mut self) -> Result<u8, LayoutError> {
        Ok(self.take::<1>()?[0])
    }
    pub fn u8s<const N: usize>(&mut self) -> Result<[u8; N], LayoutError> {
        self.take::<N>()
    }
    pub fn u16(&mut self) -> Result<u16, LayoutError> {
        self.align(2);
        Ok(u16::from_le_bytes(self.take()?))
    }
    pub fn i16(&mut self) -> Result<i16, LayoutError> {
        Ok(self.u16()? as i16)
    }
    pub fn u32(&mut self) -> Result<u32, LayoutError> {
        self.align(4);
        Ok(u32::from_le_bytes(self.take()?))
    }
    pub fn i32(&mut self) -> Result<i32, LayoutError> {
        Ok(self.u32()? as i32)
    }
    pub fn f32(&mut self) -> Result<f32, LayoutError> {
        Ok(f32::from_bits(self.u32()?))
    }

    pub fn nested<T: IdlStruct>(&mut self) -> Result<T, LayoutError> {
        if self.layout == Layout::CStruct {
            self.align(T::ALIGN);
        }
        let v = T::read(self)?;
        if self.layout == Layout::CStruct {
            self.align(T::ALIGN);
        }
        Ok(v)
    }

    /// `N` values read by `f` (a fixed IDL array: no length on the wire).
    pub fn array<T: Copy + Default, const N: usize>(
        &mut self,
        mut f: impl FnMut(&mut Self) -> Result<T, LayoutError>,
    ) -> Result<[T; N], LayoutError> {
        let mut out = [T::default(); N];
        for v in out.iter_mut() {
            *v = f(self)?;
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// struct Inner { u8 a; u32 b; }  struct Outer { u16 h; Inner i; u8 t; }
    #[derive(Debug, Default, Clone, Copy, PartialEq)]
    struct Inner {
        a: u8,
        b: u32,
    }
    #[derive(Debug, Default, Clone, Copy, PartialEq)]
    struct Outer {
        h: u16,
        i: Inner,
        t: u8,
    }
    impl IdlStruct for Inner {
        const ALIGN: usize = 4;
        fn write(&self, w: &mut IdlWriter) {
            w.u8(self.a);
            w.u32(self.b);
        }
        fn read(r: &mut IdlReader) -> Result<Self, LayoutError> {
            Ok(Inner {
                a: r.u8()?,
                b: r.u32()?,
            })
        }
    }
    impl IdlStruct for Outer {
        const ALIGN: usize = 4;
        fn write(&self, w: &mut IdlWriter) {
            w.u16(self.h);
            w.nested(&self.i);
            w.u8(self.t);
        }
        fn read(r: &mut IdlReader) -> Result<Self, LayoutError> {
            Ok(Outer {
                h: r.u16()?,
                i: r.nested()?,
                t: r.u8()?,
            })
        }
    }

    #[test]
    fn nested_structs_are_padded_in_memory_only() {
        let v = Outer {
            h: 0x0102,
            i: Inner {
                a: 3,
                b: 0x0405_0607,
            },
            t: 8,
        };
        // CDR: h@0, a@2, b@4 (aligned from the body's start), t@8.
        let cdr = to_bytes(&v, Layout::Cdr);
        assert_eq!(cdr, [2, 1, 3, 0, 7, 6, 5, 4, 8]);
        // C: h@0, Inner@4 (a@4, b@8), t@12, sizeof 16.
        let c = to_bytes(&v, Layout::CStruct);
        assert_eq!(c, [2, 1, 0, 0, 3, 0, 0, 0, 7, 6, 5, 4, 8, 0, 0, 0]);
        for (bytes, layout) in [(&cdr, Layout::Cdr), (&c, Layout::CStruct)] {
            assert_eq!(Outer::read(&mut IdlReader::new(bytes, layout)).unwrap(), v);
            assert!(Outer::read(&mut IdlReader::new(&bytes[..7], layout)).is_err());
        }
    }
}
