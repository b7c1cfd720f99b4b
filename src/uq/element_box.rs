//! A sub-box (an *element*) of the standard box `[-1, 1]^d`, and the affine map between its own
//! standard coordinates and the whole box's (docs/method.md §12).
//!
//! `η ∈ [-1, 1]^d (the element's standard coordinates) ⇒ ξ = c + r ∘ η (the whole box's)`
//!
//! An element is fitted like a whole box in its own η: a design, a surrogate and its bounds there
//! are exactly those of a study whose box is the element. Splitting halves it along chosen
//! dimensions; the children tile it without overlap (they share faces).

/// A sub-box of `[-1, 1]^d`: centre `c` and half-widths `r` in the whole box's coordinates ξ.
#[derive(Clone, Debug, PartialEq)]
pub struct ElementBox {
    /// The centre `c`, length d.
    pub center: Vec<f64>,
    /// The half-widths `r > 0`, length d.
    pub half_width: Vec<f64>,
}

impl ElementBox {
    /// The whole box `[-1, 1]^d`.
    pub fn whole(dim: usize) -> ElementBox {
        ElementBox {
            center: vec![0.0; dim],
            half_width: vec![1.0; dim],
        }
    }

    /// The dimension d.
    pub fn dim(&self) -> usize {
        self.center.len()
    }

    /// Whether this is the whole box.
    pub fn is_whole(&self) -> bool {
        self.center.iter().all(|&c| c == 0.0) && self.half_width.iter().all(|&r| r == 1.0)
    }

    /// The whole box's coordinates of the element's point `local` (ξ = c + r ∘ η).
    pub fn to_whole(&self, local: &[f64]) -> Vec<f64> {
        local
            .iter()
            .zip(self.center.iter().zip(&self.half_width))
            .map(|(&eta, (&c, &r))| c + r * eta)
            .collect()
    }

    /// [`ElementBox::to_whole`] of every row of `rows` (row-major, `n × d`).
    pub fn rows_to_whole(&self, rows: &[f64]) -> Vec<f64> {
        let d = self.dim().max(1);
        rows.chunks_exact(d)
            .flat_map(|row| self.to_whole(row))
            .collect()
    }

    /// The element's coordinates η of the whole box's point `whole` (may lie outside `[-1, 1]`
    /// when the point is outside the element).
    pub fn to_local(&self, whole: &[f64]) -> Vec<f64> {
        whole
            .iter()
            .zip(self.center.iter().zip(&self.half_width))
            .map(|(&xi, (&c, &r))| (xi - c) / r)
            .collect()
    }

    /// Whether the whole box's point `whole` lies in the element (faces included).
    pub fn contains(&self, whole: &[f64]) -> bool {
        whole
            .iter()
            .zip(self.center.iter().zip(&self.half_width))
            .all(|(&xi, (&c, &r))| xi >= c - r && xi <= c + r)
    }

    /// The element's share of the whole box's volume.
    pub fn volume_fraction(&self) -> f64 {
        self.half_width.iter().product()
    }

    /// The `2^k` children that halve the element along each of `dims` (distinct, each < d), in
    /// lexicographic order of their sides (the first of `dims` slowest, the lower half first).
    pub fn split(&self, dims: &[usize]) -> Vec<ElementBox> {
        let mut children = vec![self.clone()];
        for &j in dims {
            children = children
                .into_iter()
                .flat_map(|parent| {
                    let half = 0.5 * parent.half_width[j];
                    [-1.0, 1.0].map(|side| {
                        let mut child = parent.clone();
                        child.half_width[j] = half;
                        child.center[j] = parent.center[j] + side * half;
                        child
                    })
                })
                .collect();
        }
        children
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn maps_both_ways_and_tiles_the_parent() {
        let whole = ElementBox::whole(3);
        assert!(whole.is_whole());
        let children = whole.split(&[0, 2]);
        assert_eq!(children.len(), 4);
        // Lower half of dimension 0 first, dimension 0 slowest.
        assert_eq!(children[0].center, vec![-0.5, 0.0, -0.5]);
        assert_eq!(children[1].center, vec![-0.5, 0.0, 0.5]);
        assert_eq!(children[3].half_width, vec![0.5, 1.0, 0.5]);
        let total: f64 = children.iter().map(ElementBox::volume_fraction).sum();
        assert_eq!(total, 1.0);
        let child = &children[3];
        let xi = child.to_whole(&[-1.0, 0.25, 1.0]);
        assert_eq!(xi, vec![0.0, 0.25, 1.0]);
        assert_eq!(child.to_local(&xi), vec![-1.0, 0.25, 1.0]);
        assert!(child.contains(&xi) && !children[0].contains(&xi));
        // A grandchild composes the maps.
        let grandchild = &child.split(&[1])[0];
        assert_eq!(grandchild.to_whole(&[1.0, 1.0, 0.0]), vec![1.0, 0.0, 0.5]);
        assert_eq!(
            grandchild.rows_to_whole(&[0.0, 0.0, 0.0, -1.0, -1.0, -1.0]),
            vec![0.5, -0.5, 0.5, 0.0, -1.0, 0.0]
        );
    }
}
