//! Block means of the six channels over the whole record, in bounded memory: blocks of 2^j
//! samples, two neighbours merged whenever more than [`MAX_BLOCKS`] are held, so a record of
//! any length ends with between MAX_BLOCKS/2 and MAX_BLOCKS blocks. What `fit` reads to tell a
//! static record from a moving one.

/// Most blocks held.
pub const MAX_BLOCKS: usize = 4096;

/// Streaming block means.
#[derive(Clone, Debug)]
pub struct BlockMeans {
    /// Samples per block (a power of two).
    len: usize,
    /// Sums of the complete blocks.
    sums: Vec<[f64; 6]>,
    /// The block being filled and its count.
    open: [f64; 6],
    count: usize,
}

impl Default for BlockMeans {
    fn default() -> Self {
        BlockMeans {
            len: 1,
            sums: Vec::new(),
            open: [0.0; 6],
            count: 0,
        }
    }
}

impl BlockMeans {
    /// Adds one sample of the six channels.
    #[inline]
    pub fn push(&mut self, v: &[f64; 6]) {
        for (o, x) in self.open.iter_mut().zip(v) {
            *o += x;
        }
        self.count += 1;
        if self.count < self.len {
            return;
        }
        self.sums.push(std::mem::take(&mut self.open));
        self.count = 0;
        if self.sums.len() > MAX_BLOCKS {
            let merged = self
                .sums
                .chunks(2)
                .filter(|c| c.len() == 2)
                .map(|c| std::array::from_fn(|i| c[0][i] + c[1][i]))
                .collect::<Vec<[f64; 6]>>();
            // An odd block out starts the next, longer one.
            if self.sums.len() % 2 == 1 {
                self.open = *self.sums.last().expect("odd count");
                self.count = self.len;
            }
            self.sums = merged;
            self.len *= 2;
        }
    }

    /// Samples per complete block.
    pub fn block_len(&self) -> usize {
        self.len
    }

    /// The means of the complete blocks.
    pub fn means(&self) -> Vec<[f64; 6]> {
        let n = self.len as f64;
        self.sums.iter().map(|s| s.map(|x| x / n)).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The means are those of consecutive blocks of the final length, whatever merging
    /// happened on the way; memory stays bounded.
    #[test]
    fn means_of_consecutive_blocks() {
        let mut b = BlockMeans::default();
        let n = 100_003usize;
        for k in 0..n {
            let x = k as f64;
            b.push(&[x, -x, 1.0, 0.0, 2.0 * x, 3.0]);
        }
        let len = b.block_len();
        let means = b.means();
        assert!(means.len() <= MAX_BLOCKS && means.len() > MAX_BLOCKS / 2);
        assert_eq!(means.len(), n / len);
        for (i, m) in means.iter().enumerate() {
            let want = (i * len) as f64 + (len as f64 - 1.0) / 2.0;
            assert_eq!(m[0], want);
            assert_eq!(m[1], -want);
            assert_eq!(m[2], 1.0);
            assert_eq!(m[4], 2.0 * want);
        }
    }
}
