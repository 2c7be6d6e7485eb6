//! Binary scalar types shared by the PLY and PCD readers.

/// A numeric type of a binary field.
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
    pub(crate) fn size(self) -> usize {
        match self {
            Self::I8 | Self::U8 => 1,
            Self::I16 | Self::U16 => 2,
            Self::I32 | Self::U32 | Self::F32 => 4,
            Self::F64 => 8,
        }
    }

    pub(crate) fn is_float(self) -> bool {
        matches!(self, Self::F32 | Self::F64)
    }

    /// Decode one value from the start of `b` (which must hold at least `size()` bytes).
    pub(crate) fn read(self, b: &[u8], little_endian: bool) -> Option<f64> {
        macro_rules! get {
            ($t:ty, $n:expr) => {{
                let arr: [u8; $n] = b.get(..$n)?.try_into().ok()?;
                if little_endian {
                    <$t>::from_le_bytes(arr)
                } else {
                    <$t>::from_be_bytes(arr)
                }
            }};
        }
        Some(match self {
            Self::I8 => f64::from(get!(i8, 1)),
            Self::U8 => f64::from(get!(u8, 1)),
            Self::I16 => f64::from(get!(i16, 2)),
            Self::U16 => f64::from(get!(u16, 2)),
            Self::I32 => f64::from(get!(i32, 4)),
            Self::U32 => f64::from(get!(u32, 4)),
            Self::F32 => f64::from(get!(f32, 4)),
            Self::F64 => get!(f64, 8),
        })
    }

    /// Parse one value written as text.
    pub(crate) fn parse(self, s: &str) -> Option<f64> {
        if self.is_float() {
            let v = s.parse::<f64>().ok()?;
            Some(if self == Self::F32 {
                f64::from(v as f32)
            } else {
                v
            })
        } else {
            let v = s.parse::<i64>().ok()?;
            let ok = match self {
                Self::I8 => i8::try_from(v).is_ok(),
                Self::U8 => u8::try_from(v).is_ok(),
                Self::I16 => i16::try_from(v).is_ok(),
                Self::U16 => u16::try_from(v).is_ok(),
                Self::I32 => i32::try_from(v).is_ok(),
                Self::U32 => u32::try_from(v).is_ok(),
                Self::F32 | Self::F64 => true,
            };
            ok.then_some(v as f64)
        }
    }

    /// A colour channel from a value of this type: 8-bit integers as they are, 16-bit
    /// integers scaled by 1/257, floats taken as 0..=1; clamped to 0..=255.
    pub(crate) fn to_channel(self, v: f64) -> u8 {
        let scaled = match self {
            Self::F32 | Self::F64 => v * 255.0,
            Self::I16 | Self::U16 => v / 257.0,
            _ => v,
        };
        if scaled.is_nan() {
            0
        } else {
            scaled.round().clamp(0.0, 255.0) as u8
        }
    }
}
