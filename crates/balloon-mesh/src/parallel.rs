//! Data-parallel iteration that follows the `parallel` cargo feature.
//!
//! With the feature (the default) `prelude` re-exports rayon's prelude, so `par_iter`,
//! `par_iter_mut` and `par_chunks_mut` run on rayon's thread pool. Without it the same method
//! names are provided by small traits over slices that return the standard sequential iterators,
//! so code written once builds either way and gives identical results (every parallel loop in
//! the workspace writes disjoint outputs and reduces in a fixed order).
//!
//! ```
//! use balloon_mesh::parallel::prelude::*;
//! let squares: Vec<f64> = [1.0, 2.0, 3.0].par_iter().map(|x| x * x).collect();
//! assert_eq!(squares, [1.0, 4.0, 9.0]);
//! ```

/// `use balloon_mesh::parallel::prelude::*;` brings the parallel (or sequential) slice methods.
pub mod prelude {
    #[cfg(feature = "parallel")]
    pub use rayon::prelude::*;

    #[cfg(not(feature = "parallel"))]
    pub use super::sequential::{ParChunksMut, ParIter, ParIterMut};
}

/// Sequential stand-ins for rayon's slice methods, used without the `parallel` feature.
#[cfg(not(feature = "parallel"))]
pub mod sequential {
    /// `par_iter` as a sequential iterator.
    pub trait ParIter<T> {
        /// The elements in order.
        fn par_iter(&self) -> std::slice::Iter<'_, T>;
    }
    impl<T> ParIter<T> for [T] {
        fn par_iter(&self) -> std::slice::Iter<'_, T> {
            self.iter()
        }
    }
    /// `par_iter_mut` as a sequential iterator.
    pub trait ParIterMut<T> {
        /// The elements in order, mutably.
        fn par_iter_mut(&mut self) -> std::slice::IterMut<'_, T>;
    }
    impl<T> ParIterMut<T> for [T] {
        fn par_iter_mut(&mut self) -> std::slice::IterMut<'_, T> {
            self.iter_mut()
        }
    }
    /// `par_chunks_mut` as a sequential iterator.
    pub trait ParChunksMut<T> {
        /// Chunks of `size` in order, mutably.
        fn par_chunks_mut(&mut self, size: usize) -> std::slice::ChunksMut<'_, T>;
    }
    impl<T> ParChunksMut<T> for [T] {
        fn par_chunks_mut(&mut self, size: usize) -> std::slice::ChunksMut<'_, T> {
            self.chunks_mut(size)
        }
    }
}
