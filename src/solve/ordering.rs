//! Fill-reducing orderings for the sparse direct solver: multilevel nested dissection.
//!
//! **Why our own.** The project must build with cargo alone, so METIS/SCOTCH (C) are out. The
//! pure-Rust candidates found on crates.io were young single-maintainer
//! crates (`feral-metis`/`feral-scotch` 0.2, `rmumps` 0.1), an ordering buried in a large
//! scientific stack (`scirs2-sparse`) or tied to CUDA (`oxicuda-solver`); none has a track record
//! we could lean on for the default solver, and all would still need the constraint handling of
//! the saddle-point systems (see [`crate::solve::linear`]) done on our side. The algorithm below is
//! the classical METIS scheme and fits in one module with its tests.
//!
//! **Algorithm** (George 1973; Karypis & Kumar 1998):
//!
//! 1. *Compression.* Vertices with the same closed neighbourhood (the velocity components of one
//!    node, say) are merged into one weighted vertex, which shrinks FEM graphs 2-3x.
//! 2. *Nested dissection.* A vertex separator `S` splits the graph into parts `A` and `B` with no
//!    edge between them; `A` and `B` are ordered recursively, then `S` last. The elimination of
//!    `A` then never touches `B`, so the fill stays inside the diagonal blocks and the separator
//!    blocks, `O(n log n)` in 2D and `O(n^{4/3})` in 3D for meshes.
//! 3. *Separators* are found by a multilevel scheme: the graph is coarsened by heavy-edge matching
//!    down to about a hundred vertices; there a separator is grown greedily (breadth-first region
//!    growing from a few random seeds, boundary of the region) and improved; it is then projected
//!    back level by level and refined on each by a vertex-separator Fiduccia-Mattheyses pass (move
//!    a separator vertex into a part, pulling its neighbours in the other part into the separator,
//!    best gain first, with a balance bound and roll-back to the best state seen). Large graphs
//!    get [`NdOptions::separators`] independent multilevel separators (computed in parallel) and
//!    keep the lightest: the top separators set most of the flops (a separator of `s` dofs is a
//!    dense `s x s` block), and their weight varies much from seed to seed. LU flops of three
//!    exported augmented blocks, mean over three seeds, 3 separators against 8: model problem 4
//!    fine (107 514 unknowns) 5.51e11 against 4.83e11 (MUMPS with METIS: 3.37e11); model
//!    problem 4, 7.61e10 against 7.31e10; Schaefer-Turek 2D-1 medium, 1.90e9 against 1.85e9.
//!    (Coarsening to 400 vertices instead of 120 gave 4.35e11 on the first but 7.63e10 and
//!    2.00e9 on the others; 12 separators for the top three subgraphs alone, 4.99e11.)
//! 4. *Leaves.* Parts below [`NdOptions::leaf_size`] vertices are ordered by faer's approximate
//!    minimum degree.
//! 5. *Parallelism.* The two parts of a separator are ordered in parallel (rayon), each with its
//!    own random stream derived from the seed, so the ordering does not depend on scheduling.
//!
//! Everything is deterministic (a fixed-seed generator), so fill and flop counts are reproducible.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::SymbolicSparseColMatRef;
use std::collections::BinaryHeap;
use thiserror::Error;

/// A failure of the ordering.
#[derive(Debug, Error, Clone, PartialEq, Eq)]
pub enum OrderingError {
    /// The adjacency arrays are inconsistent (wrong lengths, index out of range).
    #[error("invalid graph: {0}")]
    InvalidGraph(String),
    /// faer's minimum-degree ordering of a leaf failed (workspace allocation).
    #[error("minimum-degree ordering of a leaf failed: {0}")]
    MinimumDegree(String),
}

/// Options of [`nested_dissection`].
#[derive(Clone, Debug)]
pub struct NdOptions {
    /// Subgraphs with at most this many (compressed) vertices are ordered by minimum degree.
    pub leaf_size: usize,
    /// Bound on the heavier part: `max(w(A), w(B)) <= imbalance * w(G) / 2`.
    pub imbalance: f64,
    /// Coarsening stops at this many vertices.
    pub coarsen_to: usize,
    /// Initial separators tried on the coarsest graph (best kept).
    pub trials: usize,
    /// Initial separators tried on the coarsest graph of a small subgraph (at most
    /// `16 * coarsen_to` vertices), where a slightly worse separator costs little.
    pub small_trials: usize,
    /// Complete multilevel separators computed for a large subgraph (more than
    /// `16 * coarsen_to` vertices); the lightest is kept.
    pub separators: usize,
    /// Maximum Fiduccia-Mattheyses passes per level.
    pub fm_passes: usize,
    /// Seed of the random generator (matching order, region-growing seeds).
    pub seed: u64,
}

impl Default for NdOptions {
    fn default() -> Self {
        NdOptions {
            leaf_size: 120,
            imbalance: 1.2,
            coarsen_to: 120,
            trials: 6,
            small_trials: 6,
            separators: 8,
            fm_passes: 4,
            seed: 0x5eed_1234_abcd_0001,
        }
    }
}

/// Nested-dissection ordering of the undirected graph given by the adjacency lists
/// `idx[ptr[v]..ptr[v + 1]]` of `n` vertices, plus the edges `extra`.
///
/// The lists need not be symmetric, sorted or free of self loops and duplicates: the graph is
/// symmetrised first. Returns `perm` with `perm[new] = old`.
pub fn nested_dissection(n: usize, ptr: &[usize], idx: &[usize], extra: &[(usize, usize)], opts: &NdOptions) -> Result<Vec<usize>, OrderingError> {
    let g = symmetric_graph(n, ptr, idx, extra)?;
    if n == 0 {
        return Ok(Vec::new());
    }
    let (cg, sv_ptr, sv_list) = compress(&g);
    let labels: Vec<usize> = (0..cg.n()).collect();
    let mut order = vec![0usize; cg.n()];
    let opts = NdOptions { leaf_size: opts.leaf_size.max(1), coarsen_to: opts.coarsen_to.max(8), trials: opts.trials.max(1), ..opts.clone() };
    dissect(&cg, &labels, &mut order, &opts, opts.seed)?;
    let mut perm = Vec::with_capacity(n);
    for &s in &order {
        perm.extend_from_slice(&sv_list[sv_ptr[s]..sv_ptr[s + 1]]);
    }
    debug_assert_eq!(perm.len(), n);
    Ok(perm)
}

/// Plain graph: sorted adjacency lists without self loops.
struct Graph {
    xadj: Vec<usize>,
    adj: Vec<usize>,
}

impl Graph {
    fn n(&self) -> usize {
        self.xadj.len() - 1
    }
    fn nbrs(&self, v: usize) -> &[usize] {
        &self.adj[self.xadj[v]..self.xadj[v + 1]]
    }
}

fn symmetric_graph(n: usize, ptr: &[usize], idx: &[usize], extra: &[(usize, usize)]) -> Result<Graph, OrderingError> {
    let bad = |m: String| OrderingError::InvalidGraph(m);
    if ptr.len() != n + 1 {
        return Err(bad(format!("{} pointers for {n} vertices", ptr.len())));
    }
    if ptr[0] != 0 || ptr.windows(2).any(|w| w[0] > w[1]) || ptr[n] > idx.len() {
        return Err(bad("pointers are not monotone or exceed the index array".into()));
    }
    if let Some(&i) = idx[..ptr[n]].iter().find(|&&i| i >= n) {
        return Err(bad(format!("neighbour {i} out of range (n = {n})")));
    }
    if let Some(&(i, j)) = extra.iter().find(|&&(i, j)| i >= n || j >= n) {
        return Err(bad(format!("extra edge ({i}, {j}) out of range (n = {n})")));
    }
    let mut deg = vec![0usize; n + 1];
    let mut count = |i: usize, j: usize| {
        if i != j {
            deg[i] += 1;
            deg[j] += 1;
        }
    };
    for v in 0..n {
        for &u in &idx[ptr[v]..ptr[v + 1]] {
            count(v, u);
        }
    }
    for &(i, j) in extra {
        count(i, j);
    }
    let mut xadj = vec![0usize; n + 1];
    for v in 0..n {
        xadj[v + 1] = xadj[v] + deg[v];
    }
    let mut fill = xadj[..n].to_vec();
    let mut adj = vec![0usize; xadj[n]];
    let mut push = |i: usize, j: usize| {
        if i != j {
            adj[fill[i]] = j;
            fill[i] += 1;
            adj[fill[j]] = i;
            fill[j] += 1;
        }
    };
    for v in 0..n {
        for &u in &idx[ptr[v]..ptr[v + 1]] {
            push(v, u);
        }
    }
    for &(i, j) in extra {
        push(i, j);
    }
    // Sort and deduplicate each list, compacting in place.
    let mut out = 0;
    let mut new_xadj = vec![0usize; n + 1];
    for v in 0..n {
        let (b, e) = (xadj[v], xadj[v + 1]);
        adj[b..e].sort_unstable();
        let start = out;
        for k in b..e {
            if out == start || adj[out - 1] != adj[k] {
                adj[out] = adj[k];
                out += 1;
            }
        }
        new_xadj[v + 1] = out;
    }
    adj.truncate(out);
    Ok(Graph { xadj: new_xadj, adj })
}

/// Weighted graph of the multilevel scheme.
#[derive(Clone)]
struct WGraph {
    xadj: Vec<usize>,
    adj: Vec<usize>,
    ew: Vec<i64>,
    vw: Vec<i64>,
}

impl WGraph {
    fn n(&self) -> usize {
        self.vw.len()
    }
    fn nbrs(&self, v: usize) -> &[usize] {
        &self.adj[self.xadj[v]..self.xadj[v + 1]]
    }
    fn total(&self) -> i64 {
        self.vw.iter().sum()
    }
}

/// Merges vertices with equal closed neighbourhoods. Returns the compressed graph (vertex weight
/// = number of merged vertices) and its members: `list[ptr[s]..ptr[s + 1]]`.
fn compress(g: &Graph) -> (WGraph, Vec<usize>, Vec<usize>) {
    let n = g.n();
    let mix = |i: usize| -> u64 {
        let mut x = (i as u64).wrapping_add(0x9e37_79b9_7f4a_7c15);
        x = (x ^ (x >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        x = (x ^ (x >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        x ^ (x >> 31)
    };
    let hash: Vec<u64> = (0..n).map(|v| g.nbrs(v).iter().fold(mix(v), |h, &u| h.wrapping_add(mix(u)))).collect();
    let mut by_key: Vec<usize> = (0..n).collect();
    by_key.sort_unstable_by_key(|&v| (hash[v], g.nbrs(v).len(), v));
    let mut rep = vec![usize::MAX; n];
    let same = |a: usize, b: usize| -> bool {
        // Closed neighbourhoods equal: N(a) \ {b} == N(b) \ {a}, and a ~ b.
        let (na, nb) = (g.nbrs(a), g.nbrs(b));
        if na.len() != nb.len() || na.binary_search(&b).is_err() {
            return false;
        }
        let mut ia = na.iter().filter(|&&x| x != b);
        let mut ib = nb.iter().filter(|&&x| x != a);
        loop {
            match (ia.next(), ib.next()) {
                (None, None) => return true,
                (Some(x), Some(y)) if x == y => {}
                _ => return false,
            }
        }
    };
    let mut k = 0;
    while k < n {
        let mut e = k + 1;
        while e < n && hash[by_key[e]] == hash[by_key[k]] && g.nbrs(by_key[e]).len() == g.nbrs(by_key[k]).len() {
            e += 1;
        }
        for a in k..e {
            let v = by_key[a];
            if rep[v] != usize::MAX {
                continue;
            }
            rep[v] = v;
            for &u in &by_key[a + 1..e] {
                if rep[u] == usize::MAX && same(v, u) {
                    rep[u] = v;
                }
            }
        }
        k = e;
    }
    // Number the supervariables by their representative's index.
    let mut id = vec![usize::MAX; n];
    let mut ns = 0;
    for v in 0..n {
        if rep[v] == v {
            id[v] = ns;
            ns += 1;
        }
    }
    let mut sv_ptr = vec![0usize; ns + 1];
    for v in 0..n {
        sv_ptr[id[rep[v]] + 1] += 1;
    }
    for s in 0..ns {
        sv_ptr[s + 1] += sv_ptr[s];
    }
    let mut fill = sv_ptr[..ns].to_vec();
    let mut sv_list = vec![0usize; n];
    for v in 0..n {
        let s = id[rep[v]];
        sv_list[fill[s]] = v;
        fill[s] += 1;
    }
    let mut xadj = vec![0usize; ns + 1];
    let mut adj = Vec::new();
    let mut vw = vec![0i64; ns];
    for s in 0..ns {
        let v = sv_list[sv_ptr[s]];
        vw[s] = (sv_ptr[s + 1] - sv_ptr[s]) as i64;
        for &u in g.nbrs(v) {
            if rep[u] == u {
                adj.push(id[u]);
            }
        }
        xadj[s + 1] = adj.len();
    }
    let ew = vec![1i64; adj.len()];
    (WGraph { xadj, adj, ew, vw }, sv_ptr, sv_list)
}

/// Small deterministic generator (xorshift64*).
struct Rng(u64);

/// A seed derived from `seed` and `k` (splitmix64 finaliser), so that independent branches of
/// the dissection get independent streams and the result does not depend on thread scheduling.
fn derive(seed: u64, k: u64) -> u64 {
    let mut x = seed ^ k.wrapping_mul(0x9e37_79b9_7f4a_7c15);
    x = (x ^ (x >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    (x ^ (x >> 31)) | 1
}

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
    fn shuffle(&mut self, v: &mut [usize]) {
        for i in (1..v.len()).rev() {
            let j = self.below(i + 1);
            v.swap(i, j);
        }
    }
}

/// Orders `g` (local vertices labelled `labels`) into `out`. The two parts are independent and
/// are ordered in parallel (rayon); each gets its own random stream derived from `seed`.
fn dissect(g: &WGraph, labels: &[usize], out: &mut [usize], opts: &NdOptions, seed: u64) -> Result<(), OrderingError> {
    let n = g.n();
    if n <= opts.leaf_size {
        return leaf_order(g, labels, out);
    }
    let part = separator(g, opts, seed);
    let mut members: [Vec<usize>; 3] = [Vec::new(), Vec::new(), Vec::new()];
    for v in 0..n {
        members[part[v] as usize].push(v);
    }
    if members[0].is_empty() || members[1].is_empty() {
        // No useful split (a clique, say): minimum degree on the whole subgraph.
        return leaf_order(g, labels, out);
    }
    let (oa, rest) = out.split_at_mut(members[0].len());
    let (ob, os) = rest.split_at_mut(members[1].len());
    for (o, &v) in os.iter_mut().zip(&members[2]) {
        *o = labels[v];
    }
    let run = |side: usize, o: &mut [usize]| -> Result<(), OrderingError> {
        let (sub, sub_labels) = induced(g, &members[side], labels);
        dissect(&sub, &sub_labels, o, opts, derive(seed, 1 + side as u64))
    };
    let (ra, rb) = if n > 4 * opts.leaf_size { rayon::join(|| run(0, oa), || run(1, ob)) } else { (run(0, oa), run(1, ob)) };
    ra.and(rb)
}

/// The subgraph induced by `vs` and its labels.
fn induced(g: &WGraph, vs: &[usize], labels: &[usize]) -> (WGraph, Vec<usize>) {
    let mut local = vec![usize::MAX; g.n()];
    for (i, &v) in vs.iter().enumerate() {
        local[v] = i;
    }
    let mut xadj = Vec::with_capacity(vs.len() + 1);
    xadj.push(0);
    let (mut adj, mut ew) = (Vec::new(), Vec::new());
    for &v in vs {
        for k in g.xadj[v]..g.xadj[v + 1] {
            let u = local[g.adj[k]];
            if u != usize::MAX {
                adj.push(u);
                ew.push(g.ew[k]);
            }
        }
        xadj.push(adj.len());
    }
    let vw = vs.iter().map(|&v| g.vw[v]).collect();
    (WGraph { xadj, adj, ew, vw }, vs.iter().map(|&v| labels[v]).collect())
}

/// Approximate minimum degree (faer) on a leaf.
fn leaf_order(g: &WGraph, labels: &[usize], out: &mut [usize]) -> Result<(), OrderingError> {
    let n = g.n();
    if n <= 2 {
        out.copy_from_slice(labels);
        return Ok(());
    }
    let mut fwd = vec![0usize; n];
    let mut inv = vec![0usize; n];
    let sym = SymbolicSparseColMatRef::new_checked(n, n, &g.xadj, None, &g.adj);
    let req = faer::sparse::linalg::amd::order_scratch::<usize>(n, g.adj.len());
    let mut mem = MemBuffer::try_new(req).map_err(|e| OrderingError::MinimumDegree(format!("{e:?}")))?;
    faer::sparse::linalg::amd::order(&mut fwd, &mut inv, sym, Default::default(), MemStack::new(&mut mem))
        .map_err(|e| OrderingError::MinimumDegree(format!("{e:?}")))?;
    for (o, &v) in out.iter_mut().zip(&fwd) {
        *o = labels[v];
    }
    Ok(())
}

/// Part of each vertex: 0 (`A`), 1 (`B`) or 2 (separator).
type Part = u8;
const SEP: Part = 2;

/// A vertex separator of `g`: the lightest of [`NdOptions::separators`] multilevel ones for a
/// large graph, a single one otherwise.
fn separator(g: &WGraph, opts: &NdOptions, seed: u64) -> Vec<Part> {
    use rayon::prelude::*;
    let tries = if g.n() > 16 * opts.coarsen_to { opts.separators.max(1) } else { 1 };
    let one = |t: usize| {
        let part = multilevel_separator(g, opts, &mut Rng(derive(seed, 100 + t as u64)));
        let pw = part_weights(g, &part);
        ((pw[2], (pw[0] - pw[1]).abs(), t), part)
    };
    let best = if tries > 1 { (0..tries).into_par_iter().map(one).min_by_key(|(s, _)| *s) } else { Some(one(0)) };
    best.map(|(_, p)| p).unwrap_or_else(|| vec![0; g.n()])
}

/// A vertex separator of `g` by the multilevel scheme.
fn multilevel_separator(g: &WGraph, opts: &NdOptions, rng: &mut Rng) -> Vec<Part> {
    let mut coarse: Vec<WGraph> = Vec::new();
    let mut cmaps: Vec<Vec<usize>> = Vec::new();
    loop {
        let cur = coarse.last().unwrap_or(g);
        if cur.n() <= opts.coarsen_to {
            break;
        }
        let (c, cmap) = coarsen(cur, opts, rng);
        if c.n() as f64 > 0.95 * cur.n() as f64 {
            break;
        }
        coarse.push(c);
        cmaps.push(cmap);
    }
    let maxw = |gr: &WGraph| ((opts.imbalance * gr.total() as f64) / 2.0).ceil() as i64;
    let coarsest = coarse.last().unwrap_or(g);
    let trials = if g.n() > 16 * opts.coarsen_to { opts.trials } else { opts.small_trials };
    let mut part = initial_separator(coarsest, maxw(coarsest), trials.max(1), opts, rng);
    for lvl in (0..coarse.len()).rev() {
        let fine = if lvl == 0 { g } else { &coarse[lvl - 1] };
        let cmap = &cmaps[lvl];
        part = (0..fine.n()).map(|v| part[cmap[v]]).collect();
        let mut pw = part_weights(fine, &part);
        fm_refine(fine, &mut part, &mut pw, maxw(fine), opts.fm_passes);
    }
    part
}

fn part_weights(g: &WGraph, part: &[Part]) -> [i64; 3] {
    let mut pw = [0i64; 3];
    for (v, &p) in part.iter().enumerate() {
        pw[p as usize] += g.vw[v];
    }
    pw
}

/// Heavy-edge matching: returns the coarse graph and the map fine -> coarse.
fn coarsen(g: &WGraph, opts: &NdOptions, rng: &mut Rng) -> (WGraph, Vec<usize>) {
    let n = g.n();
    let maxvw = (1.5 * g.total() as f64 / opts.coarsen_to as f64).ceil().max(1.0) as i64;
    let mut visit: Vec<usize> = (0..n).collect();
    rng.shuffle(&mut visit);
    let mut mate = vec![usize::MAX; n];
    for &v in &visit {
        if mate[v] != usize::MAX {
            continue;
        }
        let mut best = usize::MAX;
        let mut best_w = i64::MIN;
        for k in g.xadj[v]..g.xadj[v + 1] {
            let u = g.adj[k];
            if mate[u] == usize::MAX && g.vw[v] + g.vw[u] <= maxvw && g.ew[k] > best_w {
                best = u;
                best_w = g.ew[k];
            }
        }
        if best == usize::MAX {
            mate[v] = v;
        } else {
            mate[v] = best;
            mate[best] = v;
        }
    }
    let mut cmap = vec![usize::MAX; n];
    let mut nc = 0;
    for v in 0..n {
        if cmap[v] == usize::MAX {
            cmap[v] = nc;
            cmap[mate[v]] = nc;
            nc += 1;
        }
    }
    let mut vw = vec![0i64; nc];
    let mut xadj = vec![0usize; nc + 1];
    let (mut adj, mut ew) = (Vec::with_capacity(g.adj.len()), Vec::with_capacity(g.adj.len()));
    let mut slot = vec![usize::MAX; nc];
    let mut c = 0;
    for v in 0..n {
        if cmap[v] != c {
            continue; // v is the second member of an earlier pair
        }
        let start = adj.len();
        let members = if mate[v] != v { [v, mate[v]] } else { [v, usize::MAX] };
        for &m in members.iter().filter(|&&m| m != usize::MAX) {
            vw[c] += g.vw[m];
            for k in g.xadj[m]..g.xadj[m + 1] {
                let cu = cmap[g.adj[k]];
                if cu == c {
                    continue;
                }
                if slot[cu] == usize::MAX {
                    slot[cu] = adj.len();
                    adj.push(cu);
                    ew.push(g.ew[k]);
                } else {
                    ew[slot[cu]] += g.ew[k];
                }
            }
        }
        for &u in &adj[start..] {
            slot[u] = usize::MAX;
        }
        xadj[c + 1] = adj.len();
        c += 1;
    }
    debug_assert_eq!(c, nc);
    (WGraph { xadj, adj, ew, vw }, cmap)
}

/// Best of several greedily grown separators on a (small) graph, each refined by FM.
fn initial_separator(g: &WGraph, maxw: i64, trials: usize, opts: &NdOptions, rng: &mut Rng) -> Vec<Part> {
    let n = g.n();
    let total = g.total();
    let mut best: Option<(Vec<Part>, (i64, i64))> = None;
    for _ in 0..trials {
        // Grow A breadth-first from a random seed (restarting in unreached components) to half
        // the weight.
        let mut part = vec![1 as Part; n];
        let mut wa = 0i64;
        let mut queue = std::collections::VecDeque::new();
        let start = rng.below(n);
        let mut next_seed = 0;
        let mut seeded = false;
        while 2 * wa < total {
            let v = match queue.pop_front() {
                Some(v) => v,
                None => {
                    let s = if !seeded {
                        seeded = true;
                        start
                    } else {
                        while next_seed < n && part[next_seed] == 0 {
                            next_seed += 1;
                        }
                        if next_seed == n {
                            break;
                        }
                        next_seed
                    };
                    part[s] = 0;
                    wa += g.vw[s];
                    s
                }
            };
            for &u in g.nbrs(v) {
                if part[u] == 1 && 2 * wa < total {
                    part[u] = 0;
                    wa += g.vw[u];
                    queue.push_back(u);
                }
            }
        }
        // Separator: the boundary of A or of B, whichever is lighter.
        let boundary = |side: Part, part: &[Part]| -> Vec<usize> {
            (0..n).filter(|&v| part[v] == side && g.nbrs(v).iter().any(|&u| part[u] == 1 - side)).collect()
        };
        let (ba, bb) = (boundary(0, &part), boundary(1, &part));
        let w = |b: &[usize]| b.iter().map(|&v| g.vw[v]).sum::<i64>();
        for v in if w(&ba) <= w(&bb) { ba } else { bb } {
            part[v] = SEP;
        }
        let mut pw = part_weights(g, &part);
        fm_refine(g, &mut part, &mut pw, maxw, opts.fm_passes);
        let score = (pw[2], (pw[0] - pw[1]).abs());
        if best.as_ref().is_none_or(|(_, s)| score < *s) {
            best = Some((part, score));
        }
    }
    best.map(|(p, _)| p).unwrap_or_else(|| vec![0; n])
}

/// Vertex-separator Fiduccia-Mattheyses refinement (both directions).
///
/// Moving a separator vertex `v` into part `t` pulls its neighbours in the other part into the
/// separator; its gain is `w(v) - w(those neighbours)`. Each pass moves separator vertices in
/// order of gain (each at most once), as long as the receiving part stays below `maxw`, and
/// rolls back to the lightest separator seen. Stops after `passes` passes or a pass without
/// improvement.
fn fm_refine(g: &WGraph, part: &mut [Part], pw: &mut [i64; 3], maxw: i64, passes: usize) {
    let n = g.n();
    if n == 0 {
        return;
    }
    let gain = |part: &[Part], v: usize, to: usize| -> i64 {
        let other = (1 - to) as Part;
        g.vw[v] - g.nbrs(v).iter().filter(|&&u| part[u] == other).map(|&u| g.vw[u]).sum::<i64>()
    };
    // Ties broken by a scrambled vertex number (deterministic, not biased by numbering).
    let tie = |v: usize| (v as u32).wrapping_mul(2_654_435_761);
    let mut locked = vec![false; n];
    let mut pulled_mark = vec![false; n];
    let mut gains = [vec![0i64; n], vec![0i64; n]];
    let mut pulled: Vec<usize> = Vec::new();
    for _ in 0..passes {
        let start = (pw[2], (pw[0] - pw[1]).abs());
        locked.iter_mut().for_each(|l| *l = false);
        let mut heaps: [BinaryHeap<(i64, u32, usize)>; 2] = [BinaryHeap::new(), BinaryHeap::new()];
        let mut nsep = 0;
        for v in 0..n {
            if part[v] == SEP {
                nsep += 1;
                for t in 0..2 {
                    gains[t][v] = gain(part, v, t);
                    heaps[t].push((gains[t][v], tie(v), v));
                }
            }
        }
        // Non-improving moves tolerated before giving up (METIS-like: a multiple of the
        // separator size, bounded).
        let limit = (2 * nsep).clamp(20, 300);
        let mut log: Vec<(usize, Part)> = Vec::new();
        let mut best = start;
        let mut best_len = 0;
        let mut since_best = 0;
        loop {
            let mut cand: [Option<(i64, usize)>; 2] = [None, None];
            for t in 0..2 {
                while let Some(&(gn, _, v)) = heaps[t].peek() {
                    if part[v] != SEP || locked[v] || gains[t][v] != gn {
                        heaps[t].pop();
                        continue;
                    }
                    if pw[t] + g.vw[v] <= maxw {
                        cand[t] = Some((gn, v));
                    }
                    break;
                }
            }
            let to = match (cand[0], cand[1]) {
                (None, None) => break,
                (Some(_), None) => 0,
                (None, Some(_)) => 1,
                (Some((g0, _)), Some((g1, _))) => usize::from(!(g0 > g1 || (g0 == g1 && pw[0] <= pw[1]))),
            };
            let (_, v) = cand[to].expect("chosen");
            heaps[to].pop();
            let other = 1 - to;
            log.push((v, SEP));
            part[v] = to as Part;
            pw[2] -= g.vw[v];
            pw[to] += g.vw[v];
            locked[v] = true;
            // Separator neighbours of v would now pull v when moved to `other`.
            pulled.clear();
            for &u in g.nbrs(v) {
                if part[u] == SEP {
                    if !locked[u] {
                        gains[other][u] -= g.vw[v];
                        heaps[other].push((gains[other][u], tie(u), u));
                    }
                } else if part[u] == other as Part {
                    pulled.push(u);
                }
            }
            for &u in &pulled {
                log.push((u, other as Part));
                part[u] = SEP;
                pulled_mark[u] = true;
                pw[other] -= g.vw[u];
                pw[2] += g.vw[u];
            }
            for &u in &pulled {
                // u left `other`: separator neighbours no longer pull it when moved to `to`.
                for &x in g.nbrs(u) {
                    if part[x] == SEP && !pulled_mark[x] && !locked[x] {
                        gains[to][x] += g.vw[u];
                        heaps[to].push((gains[to][x], tie(x), x));
                    }
                }
            }
            for &u in &pulled {
                pulled_mark[u] = false;
                if !locked[u] {
                    for t in 0..2 {
                        gains[t][u] = gain(part, u, t);
                        heaps[t].push((gains[t][u], tie(u), u));
                    }
                }
            }
            let score = (pw[2], (pw[0] - pw[1]).abs());
            if score < best {
                best = score;
                best_len = log.len();
                since_best = 0;
            } else {
                since_best += 1;
                if since_best > limit {
                    break;
                }
            }
        }
        for &(u, prev) in log[best_len..].iter().rev() {
            pw[part[u] as usize] -= g.vw[u];
            part[u] = prev;
            pw[prev as usize] += g.vw[u];
        }
        if best >= start {
            break;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 5-point grid graph `nx x ny`.
    fn grid(nx: usize, ny: usize) -> (usize, Vec<usize>, Vec<usize>) {
        let n = nx * ny;
        let mut ptr = vec![0];
        let mut idx = Vec::new();
        for j in 0..ny {
            for i in 0..nx {
                if i > 0 {
                    idx.push(j * nx + i - 1);
                }
                if i + 1 < nx {
                    idx.push(j * nx + i + 1);
                }
                if j > 0 {
                    idx.push((j - 1) * nx + i);
                }
                if j + 1 < ny {
                    idx.push((j + 1) * nx + i);
                }
                ptr.push(idx.len());
            }
        }
        (n, ptr, idx)
    }

    fn is_permutation(p: &[usize], n: usize) -> bool {
        let mut seen = vec![false; n];
        p.len() == n && p.iter().all(|&i| i < n && !std::mem::replace(&mut seen[i], true))
    }

    #[test]
    fn odd_inputs() {
        let o = NdOptions::default();
        assert_eq!(nested_dissection(0, &[0], &[], &[], &o).unwrap(), Vec::<usize>::new());
        assert_eq!(nested_dissection(1, &[0, 0], &[], &[], &o).unwrap(), vec![0]);
        assert_eq!(nested_dissection(1, &[0, 1], &[0], &[], &o).unwrap(), vec![0]);
        assert!(matches!(nested_dissection(2, &[0, 1], &[0], &[], &o), Err(OrderingError::InvalidGraph(_))));
        assert!(matches!(nested_dissection(2, &[0, 1, 2], &[1, 5], &[], &o), Err(OrderingError::InvalidGraph(_))));
        assert!(matches!(nested_dissection(2, &[0, 0, 0], &[], &[(0, 2)], &o), Err(OrderingError::InvalidGraph(_))));
        // No edges at all, and many components.
        let n = 1000;
        let p = nested_dissection(n, &vec![0; n + 1], &[], &[], &NdOptions { leaf_size: 8, ..o.clone() }).unwrap();
        assert!(is_permutation(&p, n));
        // Two disconnected grids.
        let (m, ptr, idx) = grid(30, 30);
        let mut ptr2 = ptr.clone();
        ptr2.extend(ptr[1..].iter().map(|&q| q + idx.len()));
        let mut idx2 = idx.clone();
        idx2.extend(idx.iter().map(|&i| i + m));
        let p = nested_dissection(2 * m, &ptr2, &idx2, &[], &NdOptions { leaf_size: 16, ..o }).unwrap();
        assert!(is_permutation(&p, 2 * m));
    }

    #[test]
    fn separators_separate_and_are_small_on_a_grid() {
        let (n, ptr, idx) = grid(60, 40);
        let g = symmetric_graph(n, &ptr, &idx, &[]).unwrap();
        let (cg, _, _) = compress(&g);
        assert_eq!(cg.n(), n, "a 5-point grid has no indistinguishable vertices");
        let opts = NdOptions::default();
        let part = separator(&cg, &opts, opts.seed);
        for v in 0..n {
            for &u in cg.nbrs(v) {
                let crosses = (part[v] == 0 && part[u] == 1) || (part[v] == 1 && part[u] == 0);
                assert!(!crosses, "edge {v}-{u} crosses");
            }
        }
        let pw = part_weights(&cg, &part);
        assert!(pw[0] > 0 && pw[1] > 0);
        assert!(pw[0].max(pw[1]) as f64 <= 1.2 * n as f64 / 2.0 + 1.0);
        // The best separator is a grid line of 40 vertices; accept a little worse.
        assert!(pw[2] <= 60, "separator of {} vertices", pw[2]);
    }

    #[test]
    fn compression_merges_identical_neighbourhoods() {
        // Two copies of each vertex of a path, every copy adjacent to every copy of its neighbours
        // and to its twin: 2 dofs per node.
        let nodes: usize = 10;
        let n = 2 * nodes;
        let mut ptr = vec![0];
        let mut idx = Vec::new();
        for v in 0..n {
            let node = v / 2;
            for m in node.saturating_sub(1)..(node + 2).min(nodes) {
                idx.extend([2 * m, 2 * m + 1]);
            }
            ptr.push(idx.len());
        }
        let g = symmetric_graph(n, &ptr, &idx, &[]).unwrap();
        let (cg, sp, sl) = compress(&g);
        assert_eq!(cg.n(), nodes);
        assert!(cg.vw.iter().all(|&w| w == 2));
        for s in 0..nodes {
            assert_eq!(sl[sp[s]] / 2, sl[sp[s] + 1] / 2);
        }
        let p = nested_dissection(n, &ptr, &idx, &[], &NdOptions { leaf_size: 2, ..Default::default() }).unwrap();
        assert!(is_permutation(&p, n));
    }

    /// Fill of the Cholesky factor of the grid Laplacian pattern under `perm` (elimination game).
    fn cholesky_fill(n: usize, ptr: &[usize], idx: &[usize], perm: &[usize]) -> usize {
        let mut inv = vec![0; n];
        for (k, &v) in perm.iter().enumerate() {
            inv[v] = k;
        }
        let mut sets: Vec<std::collections::BTreeSet<usize>> = vec![Default::default(); n];
        for v in 0..n {
            for &u in &idx[ptr[v]..ptr[v + 1]] {
                let (a, b) = (inv[v], inv[u]);
                if a < b {
                    sets[a].insert(b);
                }
            }
        }
        let mut total = 0;
        for k in 0..n {
            let s = std::mem::take(&mut sets[k]);
            total += s.len();
            if let Some(&p) = s.iter().next() {
                for &x in s.iter().skip(1) {
                    sets[p].insert(x);
                }
            }
        }
        total
    }

    #[test]
    fn nested_dissection_beats_natural_order_on_a_grid() {
        let (n, ptr, idx) = grid(50, 50);
        let p = nested_dissection(n, &ptr, &idx, &[], &NdOptions { leaf_size: 30, ..Default::default() }).unwrap();
        assert!(is_permutation(&p, n));
        let natural: Vec<usize> = (0..n).collect();
        let (f_nd, f_nat) = (cholesky_fill(n, &ptr, &idx, &p), cholesky_fill(n, &ptr, &idx, &natural));
        assert!(f_nd * 2 < f_nat, "nd fill {f_nd}, natural (band) fill {f_nat}");
    }
}
