"""A spline basis cut at the walls, and its GMRF prior (``GPSettings.barrier`` with ``barrier_basis = "cut"``).

The barrier prior of :mod:`regression.gmrf` cuts the lattice links through walls, but the field is still
``f(x) = m + sum_n B_n(x) c_n`` with tensor-product cubic B-splines whose supports (4 h x 4 h) may straddle a wall:
such a node is informed by the data on both sides and a jump across a thin wall is smoothed over about +-2 h.
Here the basis is cut too -- the cut-cell / extended finite-element idea (Belytschko & Black 1999; Moës, Dolbow &
Belytschko 1999, "A finite element method for crack growth without remeshing"; for the SPDE prior on such a mesh,
Bakka et al. 2019): the support of a B-spline is split by the walls into the pieces that are connected *within the
support* (4-connected free samples of the blocked-space predicate); a node whose support falls apart into k > 1
pieces gets k copies, copy p being ``B_n`` restricted to piece p:

    f(x) = m + sum_n B_n(x) c_{n, piece_n(x)}.

In each piece the field is the same C^2 spline; across a wall that separates the pieces it may jump.  A wall
with a door within the support leaves the support connected: no copy, the field stays smooth through the door.

*The prior.*  The GMRF lattice of :mod:`regression.gmrf` carries the copies as nodes of their own: two copies of
lattice neighbours n, m are linked when their pieces overlap inside supp(n) and supp(m) (a free sample where n is
in the one piece and m in the other), so that the links of the copies on either side of a wall stay on their
side; a link between two nodes neither of which is copied is cut as in the barrier prior (its segment crosses
blocked space).  With no node copied the model *is* the barrier prior.  The operator K = I + t_x L_x + t_y L_y on
this graph, Q_0 = a_0 K^alpha and the per-node normalisation are those of :func:`regression.gmrf.barrier_prior`; the
normalisation evaluates each copy's prior variance at the sample of its piece where its B-spline is largest (the
node's centre for the copy whose piece holds it).

*Layout.*  Copies of a node of x-column i are stored in the block of column i, after the column's g_y original
nodes, and every block is padded to the same size b = g_y + (most copies in a column) with dummy nodes (Q = 1, no
data; they add nothing to the log marginal likelihood): the posterior precision keeps the block band of width 3 of
:mod:`regression.banded`, at (b / g_y)^3 times the cost.  Or by y-rows, whichever is cheaper: a wall along y through
the lattice doubles the blocks of the 3-4 columns it crosses (b ~ 2 g_y, ~7x the cost) but adds only ~4 nodes to each
row (b = g_x + 4, ~1.3x).

*Sufficient statistics.*  A spline cell whose 16 active nodes' pieces do not all agree over the cell falls apart
into *groups* of samples with the same pieces; the GP keeps the power sums per (cell, group) (:meth:`CutBasis.locate`),
which are again exact: within a group the 16 weights are the cell's polynomials.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage, sparse

from . import banded
from .basis import bspline_weights
from .gmrf import WIDTH

__all__ = ["CutBasis", "CutPrior", "cut_prior", "cut_prior_derivative"]

#: samples per spline cell at most (a finer step is coarsened to h / this)
MAX_SAMPLES_PER_CELL = 32


def _bspline_1d(u: np.ndarray) -> np.ndarray:
    """The centred cubic B-spline of unit spacing at u (support [-2, 2])."""
    a = np.abs(u)
    return np.where(a < 1.0, (4.0 - 6.0 * a * a + 3.0 * a ** 3) / 6.0, np.where(a < 2.0, (2.0 - a) ** 3 / 6.0, 0.0))


class CutBasis:
    """The pieces of every B-spline support of the lattice ``ax`` x ``ay`` (:class:`regression.basis.SplineAxis`)
    cut by the blocked space ``blocked`` ((m, 2) world points -> (m,) bool), sampled every ``step`` at most
    (module docstring).  ``to_world``: lattice-frame points -> world points; ``box``: world points are clipped into
    it first (beyond the domain nothing is blocked but its edge); ``cuts``: the lattice links through blocked space
    (:func:`regression.gmrf.lattice_cuts`) for the links between nodes that are not copied.

    Attributes: ``gx``, ``gy``, ``axis`` (0: blocks of x-columns, 1: of y-rows), ``n_blocks``, ``block`` (b, the
    padded block size), ``size`` (n_blocks b), ``home`` (gx, gy) the extended index of each node's first copy,
    ``split`` (True if any node has more than one piece), ``real`` (size,) bool (False: a dummy), ``links_x``/``links_y`` (pairs of extended
    indices), ``n_groups`` and ``group_ids`` (n_groups, 16) extended indices of each (cell, group)."""

    def __init__(self, ax, ay, blocked, step: float, cuts, to_world=None, box=None):
        self.gx, self.gy = gx, gy = ax.n_nodes, ay.n_nodes
        self.ax, self.ay = ax, ay
        h = min(ax.h, ay.h)
        m = max(2, min(MAX_SAMPLES_PER_CELL, int(math.ceil(h / float(step) - 1e-9))))
        self.m = m
        sx, sy = ax.h / m, ay.h / m
        self.sample = (sx, sy)
        # samples at cell-aligned centres over [node_0 - 2h, node_last + 2h]: node n's support is samples [n m, (n+4) m)
        ux = ax.nodes[0] - 2.0 * ax.h + (np.arange((gx + 3) * m) + 0.5) * sx
        uy = ay.nodes[0] - 2.0 * ay.h + (np.arange((gy + 3) * m) + 0.5) * sy
        self.origin = (ax.nodes[0] - 2.0 * ax.h, ay.nodes[0] - 2.0 * ay.h)
        U = np.stack(np.meshgrid(ux, uy, indexing="ij"), axis=-1).reshape(-1, 2)
        P = U if to_world is None else to_world(U)
        if box is not None:
            P = np.column_stack([np.clip(P[:, 0], box[0], box[1]), np.clip(P[:, 1], box[2], box[3])])
        blocked_s = np.asarray(blocked(P), bool).reshape(len(ux), len(uy))
        self.blocked = blocked_s
        # per node: its number of pieces and, when > 1, the (4m, 4m) piece label of every sample (blocked samples
        # take the nearest free sample's piece)
        csum = np.pad(blocked_s.astype(np.int64).cumsum(0).cumsum(1), ((1, 0), (1, 0)))
        w = 4 * m
        any_blocked = (csum[w:, w:] - csum[:-w, w:] - csum[w:, :-w] + csum[:-w, :-w])[::m, ::m][:gx, :gy] > 0
        self.pieces = np.ones((gx, gy), np.int64)
        self.labels: dict = {}
        bx = _bspline_1d((np.arange(w) + 0.5) / m - 2.0)             # a node's B-spline along a window axis
        self._bx = bx
        centre = 2 * m                                                # the window sample nearest the node centre
        for i, j in zip(*np.nonzero(any_blocked)):
            win = ~blocked_s[i * m:(i + 4) * m, j * m:(j + 4) * m]
            lab, k = ndimage.label(win)
            if k <= 1:
                continue
            idx = ndimage.distance_transform_edt(lab == 0, return_distances=False, return_indices=True)
            lab = lab[idx[0], idx[1]] - 1
            c = int(lab[centre, centre])                              # the piece of the centre keeps the node's slot
            if c:
                lab = np.where(lab == c, 0, np.where(lab == 0, c, lab))
            self.labels[(int(i), int(j))] = lab.astype(np.int16)
            self.pieces[i, j] = k
        self.split = bool(self.labels)
        # blocks along the axis that gives the cheaper block band (n_blocks b^3): a wall along y puts its copies in a
        # few x-columns, which would double their blocks, but adds only a few nodes to each y-row
        extra = (self.pieces - 1).sum(axis=1), (self.pieces - 1).sum(axis=0)
        b0, b1 = gy + int(extra[0].max()), gx + int(extra[1].max())
        self.axis = 0 if gx * b0 ** 3 <= gy * b1 ** 3 else 1
        inner = (gy, gx)[self.axis]
        b = (b0, b1)[self.axis]
        self.n_blocks = (gx, gy)[self.axis]
        self.block, self.size = b, self.n_blocks * b
        # extended indices: copy 0 of (i, j) at k b + (its place in the block), k = i (axis 0) or j (axis 1); copies
        # 1 .. k-1 of the block's nodes after its lattice nodes, then dummies
        i, j = np.meshgrid(np.arange(gx), np.arange(gy), indexing="ij")
        self.home = i * b + j if self.axis == 0 else j * b + i
        self.copy_base = np.full((gx, gy), -1, np.int64)
        nxt = np.full(self.n_blocks, inner, np.int64)
        self.real = np.zeros(self.size, bool)
        self.real[self.home.reshape(-1)] = True
        self.owner = {}                                               # extended index -> (i, j, piece)
        for (i, j), lab in sorted(self.labels.items()):
            k = int(self.pieces[i, j])
            blk = (i, j)[self.axis]
            self.copy_base[i, j] = blk * b + nxt[blk]
            for p in range(1, k):
                e = blk * b + nxt[blk] + p - 1
                self.real[e] = True
                self.owner[e] = (i, j, p)
            nxt[blk] += k - 1
        self._links(cuts)
        self._cells()
        self._representatives()
        self._pattern = self._rep_where = None           # caches of cut_prior

    # ------------------------------------------------------------------ indices
    def ext(self, i, j, piece) -> np.ndarray:
        """Extended indices of node(s) (i, j) in piece(s) ``piece`` (arrays broadcast)."""
        i, j, piece = np.broadcast_arrays(np.asarray(i), np.asarray(j), np.asarray(piece))
        base = np.where(piece > 0, self.copy_base[i, j] + piece - 1, self.home[i, j])
        return base

    def _piece_at(self, i: int, j: int, kx: np.ndarray, ky: np.ndarray) -> np.ndarray:
        """The piece of node (i, j) at global samples (kx, ky) inside its support."""
        lab = self.labels.get((i, j))
        if lab is None:
            return np.zeros(np.broadcast(kx, ky).shape, np.int64)
        m = self.m
        return lab[np.clip(kx - i * m, 0, 4 * m - 1), np.clip(ky - j * m, 0, 4 * m - 1)]

    def _links(self, cuts) -> None:
        gx, gy, m = self.gx, self.gy, self.m
        cut_x, cut_y = cuts
        out = []
        for axis, cut in ((0, cut_x), (1, cut_y)):
            pairs = []
            di, dj = (1, 0) if axis == 0 else (0, 1)
            ni, nj = gx - di, gy - dj
            ii, jj = np.meshgrid(np.arange(ni), np.arange(nj), indexing="ij")
            plain = np.ones((ni, nj), bool)
            for (i, j) in self.labels:
                for (a, c) in ((i, j), (i - di, j - dj)):
                    if 0 <= a < ni and 0 <= c < nj:
                        plain[a, c] = False
            keep = plain & ~np.asarray(cut, bool)
            pairs.append(np.column_stack([self.home[ii[keep], jj[keep]], self.home[ii[keep] + di, jj[keep] + dj]]))
            for a, c in zip(*np.nonzero(~plain)):
                a, c = int(a), int(c)
                # the overlap of the two supports: samples [(a+di) m, (a+4) m) x [(c+dj) m, (c+4) m)
                kx = np.arange((a + di) * m, (a + 4) * m)
                ky = np.arange((c + dj) * m, (c + 4) * m)
                KX, KY = np.meshgrid(kx, ky, indexing="ij")
                free = ~self.blocked[KX, KY]
                if not free.any():
                    continue
                p1 = self._piece_at(a, c, KX[free], KY[free])
                p2 = self._piece_at(a + di, c + dj, KX[free], KY[free])
                combo = np.unique(p1.astype(np.int64) * 1000 + p2)
                e1 = self.ext(a, c, combo // 1000)
                e2 = self.ext(a + di, c + dj, combo % 1000)
                pairs.append(np.column_stack([np.atleast_1d(e1), np.atleast_1d(e2)]))
            out.append(np.concatenate(pairs).astype(np.int64))
        self.links_x, self.links_y = out

    def _cells(self) -> None:
        """The groups of every spline cell: ``cell_first`` (n_cells,) its first group, ``group_map`` (n_split, m, m)
        the group (relative to the first) of each sample of a split cell, ``cell_split`` (n_cells,) its row in
        ``group_map`` (-1: one group), ``group_ids`` (n_groups, 16)."""
        ncx, ncy, m, gy = self.ax.n_cells, self.ay.n_cells, self.m, self.gy
        o = np.arange(4)
        first = np.empty(ncx * ncy, np.int64)
        split_row = np.full(ncx * ncy, -1, np.int64)
        ids, maps = [], []
        copied = np.zeros((self.gx, gy), bool)
        for (i, j) in self.labels:
            copied[i, j] = True
        # cells whose 16 active nodes include a copied one
        win = np.zeros((ncx, ncy), bool)
        for p in range(4):
            for q in range(4):
                win |= copied[p:p + ncx, q:q + ncy]
        ci, cj = np.meshgrid(np.arange(ncx), np.arange(ncy), indexing="ij")
        base = self.home[ci[:, :, None, None] + o[:, None], cj[:, :, None, None] + o[None, :]].reshape(ncx * ncy, 16)
        n = 0
        for c in range(ncx * ncy):
            i, j = divmod(c, ncy)
            first[c] = n
            if not win[i, j]:
                ids.append(base[c][None])
                n += 1
                continue
            kx = np.arange((i + 3) * m, (i + 4) * m)
            ky = np.arange((j + 3) * m, (j + 4) * m)
            KX, KY = np.meshgrid(kx, ky, indexing="ij")
            pc = np.stack([self._piece_at(i + p, j + q, KX, KY) for p in range(4) for q in range(4)], axis=-1)
            sig, inv = np.unique(pc.reshape(m * m, 16), axis=0, return_inverse=True)
            nodes_i = np.repeat(i + o, 4)
            nodes_j = np.tile(j + o, 4)
            ids.append(self.ext(nodes_i[None, :], nodes_j[None, :], sig))
            if len(sig) > 1:
                split_row[c] = len(maps)
                maps.append(inv.reshape(m, m))
            n += len(sig)
        self.cell_first, self.cell_split = first, split_row
        self.group_map = np.array(maps, np.int16).reshape(-1, m, m)
        self.group_ids = np.concatenate(ids).astype(np.int64)
        self.n_groups = n

    def locate(self, U: np.ndarray) -> np.ndarray:
        """The (cell, group) index of lattice-frame points ``U`` (n, 2) inside the lattice's cells."""
        ix, tx = self.ax.locate(U[:, 0])
        iy, ty = self.ay.locate(U[:, 1])
        cell = ix * self.ay.n_cells + iy
        g = self.cell_first[cell].copy()
        row = self.cell_split[cell]
        s = row >= 0
        if s.any():
            m = self.m
            kx = np.clip(np.floor(tx[s] * m), 0, m - 1).astype(np.int64)
            ky = np.clip(np.floor(ty[s] * m), 0, m - 1).astype(np.int64)
            g[s] += self.group_map[row[s], kx, ky]
        return g

    def basis(self, U: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(extended indices (n, 16), weights (n, 16)) of the points ``U`` (lattice frame)."""
        _, tx = self.ax.locate(U[:, 0])
        _, ty = self.ay.locate(U[:, 1])
        phi = (bspline_weights(tx)[:, :, None] * bspline_weights(ty)[:, None, :]).reshape(len(U), 16)
        return self.group_ids[self.locate(U)], phi

    def _representatives(self) -> None:
        """Per real extended node: the sample of its piece where its B-spline is largest, as (extended indices (16,),
        weights (16,)) of the field there (``rep_ids``, ``rep_phi``, (n_real, 16)) and the row of each node in
        them (``rep_row``, (size,), -1 for dummies)."""
        gx, gy, m = self.gx, self.gy, self.m
        pts = np.empty((self.size, 2))
        sx, sy = self.sample
        # copy 0: the node centre clipped into the lattice's cells (its centre is in piece 0 by construction)
        i, j = np.meshgrid(np.arange(gx), np.arange(gy), indexing="ij")
        e0 = self.home.reshape(-1)
        pts[e0, 0] = np.clip(self.ax.nodes[i.reshape(-1)], self.ax.lo, self.ax.hi)
        pts[e0, 1] = np.clip(self.ay.nodes[j.reshape(-1)], self.ay.lo, self.ay.hi)
        weight = self._bx[:, None] * self._bx[None, :]
        for (a, c), lab in self.labels.items():
            for p in range(int(self.pieces[a, c])):
                e = int(self.ext(a, c, p))
                # samples of the piece inside the lattice's cells (a node beyond the ends has part of its support out)
                kx = np.arange(4 * m) + a * m
                ky = np.arange(4 * m) + c * m
                inside = ((kx >= 3 * m) & (kx < (self.ax.n_cells + 3) * m))[:, None] & \
                         ((ky >= 3 * m) & (ky < (self.ay.n_cells + 3) * m))[None, :]
                free = ~self.blocked[a * m:(a + 4) * m, c * m:(c + 4) * m]
                score = np.where((lab == p) & inside, weight * (1.0 + free), -1.0)
                k = int(np.argmax(score))
                u, v = divmod(k, 4 * m)
                pts[e] = (self.origin[0] + (a * m + u + 0.5) * sx, self.origin[1] + (c * m + v + 0.5) * sy)
        rows = np.flatnonzero(self.real)
        ids, phi = self.basis(pts[rows])
        # the node itself must be among its representative's 16 (its piece there is its own)
        if not np.all((ids == rows[:, None]).any(axis=1)):
            bad = rows[~(ids == rows[:, None]).any(axis=1)]
            # a piece with no sample inside the lattice's cells: its copy carries no data; represent it by itself
            for e in bad:
                r = int(np.flatnonzero(rows == e)[0])
                ids[r] = e
                phi[r] = 0.0
                phi[r, 0] = 1.0
        self.rep_ids, self.rep_phi = ids, phi
        self.rep_row = np.full(self.size, -1, np.int64)
        self.rep_row[rows] = np.arange(len(rows))

    # ------------------------------------------------------------------ band positions
    def band_index(self, e1: np.ndarray, e2: np.ndarray) -> np.ndarray:
        """Flat positions of the entries (e1, e2) (blocks at most 3 apart) in a lower block band
        (n_blocks, 4, b, b) of :mod:`regression.banded` (symmetric: (e2, e1) when e2's block is the larger)."""
        b = self.block
        k1, r1 = np.divmod(e1, b)
        k2, r2 = np.divmod(e2, b)
        swap = k1 < k2
        ka, kb = np.where(swap, k2, k1), np.where(swap, k1, k2)
        ra, rb = np.where(swap, r2, r1), np.where(swap, r1, r2)
        return ((kb * (WIDTH + 1) + (ka - kb)) * b + ra) * b + rb

    def scatter_index(self) -> tuple[np.ndarray, np.ndarray]:
        """(pairs kept (p, q) of a group's 16 x 16, flat block-band positions (n_groups, kept)) for A's lower
        block band: every pair whose row column is below (or in) its column's block, (p, q) and (q, p) both for the
        diagonal blocks."""
        e1 = self.group_ids[:, :, None]
        e2 = self.group_ids[:, None, :]
        k1, k2 = e1 // self.block, e2 // self.block
        keep = np.broadcast_to(k1 >= k2, (self.n_groups, 16, 16))
        flat = np.where(keep, self.band_index(np.broadcast_to(e1, keep.shape), np.broadcast_to(e2, keep.shape)), -1)
        return keep.reshape(self.n_groups, 256), flat.reshape(self.n_groups, 256)


@dataclass(frozen=True)
class CutPrior:
    """The normalised GMRF prior of a :class:`CutBasis` at unit s_f^2 (module docstring): ``precision`` Q as a
    block band (gx, 4, b, b), ``logdet`` log det Q (dummies: Q = 1), ``cov`` Q^{-1} within the block band,
    ``scale`` the per-node scale (size,)."""
    precision: np.ndarray
    logdet: float
    cov: np.ndarray
    scale: np.ndarray
    basis: CutBasis = field(repr=False)
    lengths: tuple = ()
    nu: int = 1


def _laplacian(n: int, links: np.ndarray, h: float) -> sparse.csr_matrix:
    w = np.full(len(links), 1.0 / (h * h))
    adj = sparse.coo_matrix((np.r_[w, w], (np.r_[links[:, 0], links[:, 1]], np.r_[links[:, 1], links[:, 0]])),
                            shape=(n, n)).tocsr()
    return sparse.diags(np.asarray(adj.sum(axis=1)).ravel()) - adj


def _outer_blocks(v: np.ndarray, gx: int, b: int) -> np.ndarray:
    """(gx, 4, b, b): v_row v_col at every entry of a lower block band, v (gx b,)."""
    v = v.reshape(gx, b)
    rows = np.zeros((gx, WIDTH + 1, b))
    for d in range(WIDTH + 1):
        rows[:gx - d, d] = v[d:]
    return rows[:, :, :, None] * v[:, None, None, :]


def _to_blocks(basis: CutBasis, q: sparse.csr_matrix) -> np.ndarray:
    """The symmetric sparse ``q`` (extended indices) as a lower block band (n_blocks, 4, b, b); the positions of its
    pattern (the same at every length scale) are kept on the basis (:func:`regression.gmrf._sparse_to_blocks`, with
    a cached index and one bincount)."""
    q.sum_duplicates()
    hit = basis._pattern
    if hit is None or not (np.array_equal(hit[0], q.indptr) and np.array_equal(hit[1], q.indices)):
        rows = np.repeat(np.arange(q.shape[0]), np.diff(q.indptr))
        k1, k2 = rows // basis.block, q.indices // basis.block
        lower = k1 >= k2
        if np.any(k1[lower] - k2[lower] > WIDTH):                  # pragma: no cover - K^alpha reaches 3 blocks
            raise AssertionError("the cut prior's precision reaches beyond the block band")
        hit = basis._pattern = (q.indptr.copy(), q.indices.copy(), lower,
                                ((k2[lower] * (WIDTH + 1) + (k1 - k2)[lower]) * basis.block + rows[lower] % basis.block)
                                * basis.block + q.indices[lower] % basis.block)
    n = basis.n_blocks * (WIDTH + 1) * basis.block * basis.block
    return np.bincount(hit[3], weights=q.data[hit[2]], minlength=n).reshape(basis.n_blocks, WIDTH + 1, basis.block,
                                                                            basis.block)


def cut_prior(basis: CutBasis, lx: float, ly: float, nu: int) -> CutPrior:
    """Q = S^{-1} Q_0 S^{-1} on the cut basis's extended lattice (module docstring): Q_0 = a_0 K^alpha with the
    Laplacians of its links, log det Q_0 and Q_0^{-1}'s band from the block-banded Cholesky factor and selected
    inverse, S from the fixed-point normalisation at the nodes' representative samples."""
    hx, hy = basis.ax.h, basis.ay.h
    n, gx, b = basis.size, basis.n_blocks, basis.block
    c = 0.5 / nu
    k = sparse.identity(n, format="csr") + c * lx * lx * _laplacian(n, basis.links_x, hx) \
        + c * ly * ly * _laplacian(n, basis.links_y, hy)
    q = k
    for _ in range(nu):
        q = q @ k
    q = q * (hx * hy / (2.0 * math.pi * lx * ly))
    dummy = ~basis.real
    if dummy.any():                                   # a dummy's row of K^alpha is its diagonal alone
        q = q + sparse.diags(np.where(dummy, 1.0 - q.diagonal(), 0.0))
    q0 = _to_blocks(basis, q.tocsr())
    factor = banded.cholesky(q0)
    logdet0 = banded.logdet(factor)
    cov0 = banded.selected_inverse(factor)
    flat = cov0.reshape(-1)
    ids, phi = basis.rep_ids, basis.rep_phi
    rows = np.flatnonzero(basis.real)
    if basis._rep_where is None:                       # the normalisation's band positions, once per basis
        basis._rep_where = (basis.band_index(ids[:, :, None], ids[:, None, :]), basis.band_index(rows, rows))
    local = flat[basis._rep_where[0]]                                                  # (n_real, 16, 16)
    diag = flat[basis._rep_where[1]]
    scale = np.ones(n)
    scale[rows] = 1.0 / np.sqrt(diag)
    for _ in range(3):
        u = phi * scale[ids]
        var = np.einsum("np,npq,nq->n", u, local, u)
        scale[rows] = scale[rows] / np.sqrt(var)
    inv = 1.0 / scale
    precision = q0 * _outer_blocks(inv, gx, b)
    cov = cov0 * _outer_blocks(scale, gx, b)
    logdet = logdet0 - 2.0 * float(np.sum(np.log(scale)))
    return CutPrior(precision, logdet, cov, scale, basis, (lx, ly), int(nu))


#: the step in log l of :func:`cut_prior_derivative`'s central differences
_STEP = 1e-4


def cut_prior_derivative(prior: CutPrior, dx: float, dy: float) -> tuple[np.ndarray, float]:
    """(dQ, d log det Q) along dx d/d log l_x + dy d/d log l_y, by central differences (two more priors)."""
    lx, ly = prior.lengths
    e = _STEP
    plus, minus = (cut_prior(prior.basis, lx * math.exp(s * e * dx), ly * math.exp(s * e * dy), prior.nu)
                   for s in (1.0, -1.0))
    return (plus.precision - minus.precision) / (2.0 * e), (plus.logdet - minus.logdet) / (2.0 * e)
