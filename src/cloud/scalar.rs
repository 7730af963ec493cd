//! The scalar types of PCD fields, PLY properties and PointCloud2 fields, read from their bytes
//! in either byte order.

/// Reads a scalar of PCD/PLY/PointField type `kind` at `bytes[..]` as f32.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    pub fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    #[inline]
    pub fn read(self, b: &[u8], big_endian: bool) -> f32 {
        self.read_f64(b, big_endian) as f32
    }

    /// The value as stored (every type here is exact in f64).
    #[inline]
    pub fn read_f64(self, b: &[u8], big_endian: bool) -> f64 {
        macro_rules! get {
            ($t:ty, $n:expr) => {{
                let a: [u8; $n] = b[..$n].try_into().unwrap();
                if big_endian {
                    <$t>::from_be_bytes(a)
                } else {
                    <$t>::from_le_bytes(a)
                }
            }};
        }
        match self {
            Scalar::I8 => b[0] as i8 as f64,
            Scalar::U8 => b[0] as f64,
            Scalar::I16 => get!(i16, 2) as f64,
            Scalar::U16 => get!(u16, 2) as f64,
            Scalar::I32 => get!(i32, 4) as f64,
            Scalar::U32 => get!(u32, 4) as f64,
            Scalar::F32 => get!(f32, 4) as f64,
            Scalar::F64 => get!(f64, 8),
        }
    }
}
