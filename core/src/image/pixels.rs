//! A gray image's bytes: owned, or lent by a caller (a NumPy array) so that the detector reads
//! them where they lie. Writing to lent bytes copies them first, so the lender's memory is
//! never changed.

use std::fmt;
use std::ops::{Deref, DerefMut};
use std::sync::Arc;

/// Bytes someone else owns, kept alive as long as any image reads them.
pub type Lent = Arc<dyn AsRef<[u8]> + Send + Sync>;

/// The row-major bytes of a [`super::GrayImage`].
#[derive(Clone)]
pub enum Pixels {
    Owned(Vec<u8>),
    Lent(Lent),
}

impl Pixels {
    /// The bytes as a vector, copied only when they were lent.
    pub fn into_vec(self) -> Vec<u8> {
        match self {
            Self::Owned(v) => v,
            Self::Lent(l) => (*l).as_ref().to_vec(),
        }
    }

    pub fn is_lent(&self) -> bool {
        matches!(self, Self::Lent(_))
    }
}

impl Deref for Pixels {
    type Target = [u8];

    fn deref(&self) -> &[u8] {
        match self {
            Self::Owned(v) => v,
            Self::Lent(l) => (**l).as_ref(),
        }
    }
}

impl DerefMut for Pixels {
    fn deref_mut(&mut self) -> &mut [u8] {
        if let Self::Lent(l) = self {
            *self = Self::Owned((**l).as_ref().to_vec());
        }
        match self {
            Self::Owned(v) => v,
            Self::Lent(_) => unreachable!("lent bytes were just copied"),
        }
    }
}

impl From<Vec<u8>> for Pixels {
    fn from(v: Vec<u8>) -> Self {
        Self::Owned(v)
    }
}

impl FromIterator<u8> for Pixels {
    fn from_iter<I: IntoIterator<Item = u8>>(bytes: I) -> Self {
        Self::Owned(bytes.into_iter().collect())
    }
}

impl PartialEq for Pixels {
    fn eq(&self, other: &Self) -> bool {
        **self == **other
    }
}

impl Eq for Pixels {}

impl fmt::Debug for Pixels {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let kind = if self.is_lent() { "lent" } else { "owned" };
        write!(f, "Pixels({} bytes, {kind})", self.len())
    }
}

impl<'a> IntoIterator for &'a Pixels {
    type Item = &'a u8;
    type IntoIter = std::slice::Iter<'a, u8>;

    fn into_iter(self) -> Self::IntoIter {
        self.iter()
    }
}

impl<'a> IntoIterator for &'a mut Pixels {
    type Item = &'a mut u8;
    type IntoIter = std::slice::IterMut<'a, u8>;

    fn into_iter(self) -> Self::IntoIter {
        self.iter_mut()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writing_to_lent_bytes_leaves_the_lender_unchanged() {
        let lender: Arc<Vec<u8>> = Arc::new(vec![1, 2, 3]);
        let mut pixels = Pixels::Lent(lender.clone());
        assert_eq!(&*pixels, &[1, 2, 3]);
        pixels[0] = 9;
        assert_eq!(&*pixels, &[9, 2, 3]);
        assert!(!pixels.is_lent());
        assert_eq!(*lender, vec![1, 2, 3]);
    }

    #[test]
    fn lent_and_owned_bytes_compare_by_content() {
        let lent = Pixels::Lent(Arc::new(vec![4u8, 5]));
        assert_eq!(lent, Pixels::from(vec![4, 5]));
        assert_eq!(lent.clone().into_vec(), vec![4, 5]);
    }
}
