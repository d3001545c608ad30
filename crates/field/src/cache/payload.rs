//! What a cache file's payload holds: the typed layout of its arrays
//! ([`StoreLayout`]), the values in and out ([`CachePayload`],
//! [`ValueReader`]) and the common flat store ([`FlatStore`]).

use ferrofmm_kernels::Real;
use serde::Serialize;
use serde::de::DeserializeOwned;

/// The typed description of what a cache file's payload holds: which
/// arrays, of which shapes, in which order (named fields, never positional
/// words). Written in the header, checked against the payload on reading.
pub(crate) trait StoreLayout: Serialize + DeserializeOwned {
    /// Number of values the arrays of this layout hold together; `Err`
    /// when the layout contradicts itself (a rank above the surface size,
    /// say).
    fn n_values(&self) -> Result<usize, String>;

    /// A check for [`load_or_compute`](super::load_or_compute) that a file's layout is exactly
    /// `self` (for layouts fixed by the parameters alone).
    fn accept(self) -> impl Fn(&Self) -> Result<(), String>
    where
        Self: PartialEq + std::fmt::Debug + Sized,
    {
        move |found| {
            if *found == self {
                Ok(())
            } else {
                Err(format!("layout {found:?}, expected {self:?}"))
            }
        }
    }
}

/// Something stored in the cache: a [`StoreLayout`] and the values of its
/// arrays, written one after another in layout order.
pub(crate) trait CachePayload<T: Real>: Sized {
    /// The layout written in the header.
    type Layout: StoreLayout;
    /// The layout of `self`.
    fn layout(&self) -> Self::Layout;
    /// The arrays, in the order the layout lists them.
    fn arrays(&self) -> Vec<&[T]>;
    /// Rebuild from a layout and its values (their number already checked
    /// against [`StoreLayout::n_values`]).
    fn from_values(layout: Self::Layout, values: Vec<T>) -> Result<Self, String>;
}

/// Reads the arrays of a payload back in layout order.
pub(crate) struct ValueReader<T> {
    values: std::vec::IntoIter<T>,
}

impl<T: Real> ValueReader<T> {
    /// A reader over `values`.
    pub fn new(values: Vec<T>) -> Self {
        ValueReader {
            values: values.into_iter(),
        }
    }

    /// The next `len` values.
    pub fn take(&mut self, len: usize) -> Result<Vec<T>, String> {
        let v: Vec<T> = self.values.by_ref().take(len).collect();
        if v.len() == len {
            Ok(v)
        } else {
            Err("payload shorter than its layout".into())
        }
    }

    /// `Err` unless every value was read.
    pub fn finish(self) -> Result<(), String> {
        if self.values.len() == 0 {
            Ok(())
        } else {
            Err("payload longer than its layout".into())
        }
    }
}

/// The payload of a scheme whose values are one flat array (slots indexed
/// by set and transfer vector): a typed layout and the array.
pub(crate) struct FlatStore<L, T> {
    /// What the values are.
    pub layout: L,
    /// The values.
    pub data: Vec<T>,
}

impl<T: Real, L: StoreLayout + Clone> CachePayload<T> for FlatStore<L, T> {
    type Layout = L;

    fn layout(&self) -> L {
        self.layout.clone()
    }

    fn arrays(&self) -> Vec<&[T]> {
        vec![&self.data]
    }

    fn from_values(layout: L, data: Vec<T>) -> Result<Self, String> {
        Ok(FlatStore { layout, data })
    }
}
