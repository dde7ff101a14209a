//! Slot allocator over fixed-size pages: hands out runs of splat slots (first fit, possibly split
//! over several runs), coalesces freed runs, and grows by whole pages when it runs out.

use std::collections::BTreeMap;

/// A run of consecutive slots `[start, start + len)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Run {
    /// First slot.
    pub start: u32,
    /// Number of slots.
    pub len: u32,
}

/// Free-run allocator over `pages * page_size` slots.
#[derive(Debug, Clone)]
pub struct SlotAllocator {
    page_size: u32,
    pages: u32,
    max_pages: u32,
    /// Free runs by start slot; never adjacent (always coalesced).
    free: BTreeMap<u32, u32>,
    used: u64,
}

impl SlotAllocator {
    /// An empty allocator of pages of `page_size` slots (at least 1), growing up to `max_pages`.
    pub fn new(page_size: u32, max_pages: u32) -> Self {
        SlotAllocator {
            page_size: page_size.max(1),
            pages: 0,
            max_pages,
            free: BTreeMap::new(),
            used: 0,
        }
    }

    /// Slots per page.
    pub fn page_size(&self) -> u32 {
        self.page_size
    }

    /// Pages allocated so far.
    pub fn pages(&self) -> u32 {
        self.pages
    }

    /// Slots handed out and not freed.
    pub fn used(&self) -> u64 {
        self.used
    }

    /// Free slots in the current pages.
    pub fn free_slots(&self) -> u64 {
        self.pages as u64 * self.page_size as u64 - self.used
    }

    /// Allocates `n` slots as one or more runs (lowest addresses first), adding pages as needed.
    /// `None` (nothing allocated) when that would exceed `max_pages`.
    pub fn alloc(&mut self, n: u32) -> Option<Vec<Run>> {
        if n == 0 {
            return Some(Vec::new());
        }
        let missing = (n as u64).saturating_sub(self.free_slots());
        if missing > 0 {
            let add = missing.div_ceil(self.page_size as u64);
            if self.pages as u64 + add > self.max_pages as u64 {
                return None;
            }
            let start = self.pages * self.page_size;
            self.pages += add as u32;
            self.release(Run {
                start,
                len: add as u32 * self.page_size,
            });
        }
        let mut out = Vec::new();
        let mut need = n;
        // Prefer a single run that fits whole; else take runs from the lowest address.
        if let Some((&s, &l)) = self.free.iter().find(|&(_, &l)| l >= need) {
            out.push(Run {
                start: s,
                len: need,
            });
            self.free.remove(&s);
            if l > need {
                self.free.insert(s + need, l - need);
            }
            need = 0;
        }
        while need > 0 {
            let (&s, &l) = self.free.iter().next()?;
            let take = l.min(need);
            self.free.remove(&s);
            if l > take {
                self.free.insert(s + take, l - take);
            }
            out.push(Run {
                start: s,
                len: take,
            });
            need -= take;
        }
        self.used += n as u64;
        Some(out)
    }

    /// Returns the runs to the free pool (coalescing with neighbours).
    pub fn free(&mut self, runs: &[Run]) {
        for &r in runs {
            if r.len == 0 {
                continue;
            }
            self.used = self.used.saturating_sub(r.len as u64);
            self.release(r);
        }
    }

    fn release(&mut self, r: Run) {
        let mut start = r.start;
        let mut len = r.len;
        if let Some((&ps, &pl)) = self.free.range(..start).next_back()
            && ps + pl == start
        {
            self.free.remove(&ps);
            start = ps;
            len += pl;
        }
        if let Some(&nl) = self.free.get(&(start + len)) {
            self.free.remove(&(start + len));
            len += nl;
        }
        self.free.insert(start, len);
    }
}

/// Splits a run into pieces that stay inside one page and one texture row each, as
/// `(page, first slot in page, len)` with rows of `row` slots: at most a partial first row, a
/// block of whole rows, and a partial last row per page.
pub fn page_pieces(run: Run, page_size: u32, row: u32) -> Vec<(u32, u32, u32)> {
    let mut out = Vec::new();
    let mut s = run.start;
    let end = run.start as u64 + run.len as u64;
    while (s as u64) < end {
        let page = s / page_size;
        let local = s % page_size;
        let page_end = ((page as u64 + 1) * page_size as u64).min(end);
        let avail = (page_end - s as u64) as u32;
        let take = if !local.is_multiple_of(row) {
            (row - local % row).min(avail)
        } else if avail >= row {
            avail - avail % row
        } else {
            avail
        };
        out.push((page, local, take));
        s += take;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn slots(runs: &[Run]) -> Vec<u32> {
        runs.iter().flat_map(|r| r.start..r.start + r.len).collect()
    }

    #[test]
    fn insert_remove_reuse_without_overlap() {
        let mut a = SlotAllocator::new(100, 10);
        let r1 = a.alloc(150).unwrap();
        assert_eq!(a.pages(), 2);
        let r2 = a.alloc(30).unwrap();
        let r3 = a.alloc(20).unwrap();
        assert_eq!(a.used(), 200);
        assert_eq!(a.free_slots(), 0);
        let mut all: Vec<u32> = [&r1, &r2, &r3].iter().flat_map(|r| slots(r)).collect();
        all.sort();
        all.dedup();
        assert_eq!(all.len(), 200, "no slot handed out twice");
        // Free the middle one; a request of the same size reuses exactly those slots.
        a.free(&r2);
        assert_eq!(a.used(), 170);
        let r4 = a.alloc(30).unwrap();
        assert_eq!(slots(&r4), slots(&r2));
        assert_eq!(a.pages(), 2, "reuse, no growth");
        // Fragmented: free r4 (30) and r3 (20, adjacent: coalesced) then ask 60: 50 reused + grow.
        a.free(&r4);
        a.free(&r3);
        assert_eq!(a.free.len(), 1, "coalesced");
        let r5 = a.alloc(60).unwrap();
        assert_eq!(a.pages(), 3);
        let mut s5 = slots(&r5);
        s5.sort();
        assert_eq!(s5.len(), 60);
        assert!(s5.iter().all(|s| !slots(&r1).contains(s)));
        assert_eq!(a.used(), 210);
        // Freeing everything coalesces into one run covering all pages.
        a.free(&r1);
        a.free(&r5);
        assert_eq!(a.used(), 0);
        assert_eq!(a.free.iter().next(), Some((&0, &300)));
    }

    #[test]
    fn page_limit_refuses_without_side_effects() {
        let mut a = SlotAllocator::new(10, 2);
        assert!(a.alloc(21).is_none());
        assert_eq!((a.pages(), a.used()), (0, 0));
        assert_eq!(a.alloc(0), Some(vec![]));
        let r = a.alloc(20).unwrap();
        assert_eq!(slots(&r), (0..20).collect::<Vec<_>>());
        assert!(a.alloc(1).is_none());
        assert_eq!(SlotAllocator::new(0, 1).page_size(), 1);
    }

    #[test]
    fn pieces_stay_in_one_page_and_row() {
        for (start, len) in [(0, 1), (5, 300), (120, 9), (250, 1000), (1023, 2)] {
            let run = Run { start, len };
            let pieces = page_pieces(run, 256, 16);
            let mut covered = Vec::new();
            for &(page, local, n) in &pieces {
                assert!(local + n <= 256);
                // One partial row or whole rows only.
                assert!(local % 16 + n <= 16 || (local % 16 == 0 && (n % 16 == 0 || n < 16)));
                covered.extend((0..n).map(|k| page * 256 + local + k));
            }
            assert_eq!(covered, (start..start + len).collect::<Vec<_>>());
        }
    }
}
