"""Where the active learner samples next (Sec. IV-A of Thakar et al.): exploration far from every
sample, exploitation between opposite-label support vectors, and the rho-aware samplers that spend
labels where the query Gaussians' success probabilities are still uncertain (committee variance,
the boundary band inside each Gaussian, the GP posterior).
"""

from __future__ import annotations

import numpy as np

from pickplan.core.meshes import farthest_points


def _nearest_dist(P, X) -> np.ndarray:
    if len(X) == 0:
        return np.full(len(P), np.inf)
    d2 = ((P[:, None, :] - X[None, :, :]) ** 2).sum(-1)
    return np.sqrt(d2.min(axis=1))


def _greedy_farthest(cands, existing, k) -> np.ndarray:
    """Pick k candidates one by one, each farthest from existing + already picked points."""
    if k <= 0 or len(cands) == 0:
        return np.zeros((0, 3))
    return np.asarray(cands)[farthest_points(cands, k, existing)]


def sample_focus(rng, n, focus_scale, focus_fraction) -> np.ndarray:
    """Mixture of N(0, focus_scale^2) (clipped to the domain) and uniform points."""
    n_f = int(round(focus_fraction * n))
    g = np.clip(rng.normal(0.0, focus_scale, size=(n_f, 3)), -1.0, 1.0)
    u = rng.uniform(-1.0, 1.0, size=(n - n_f, 3))
    return np.vstack([g, u])


def explore(
    rng, X, k, n_candidates, focus_scale=0.25, focus_fraction=0.0, query_sigmas=(), query_fraction=0.0
) -> np.ndarray:
    """Random samples biased toward regions with few samples (farthest-point selection
    among random candidates drawn from the focus mixture). A share query_fraction of them
    comes from the query Gaussians N(0, query_sigma), farthest-point in that Gaussian's own
    scale: the interior of a success region is rarely sampled otherwise, and an RBF
    classifier falls back to its bias (failure) in unsampled space."""
    picked = []
    n_q = int(round(query_fraction * k)) if len(query_sigmas) else 0
    for i, sig in enumerate(query_sigmas):
        k_i = n_q // len(query_sigmas) + (i < n_q % len(query_sigmas))
        sig = np.asarray(sig, dtype=float)
        cands = np.clip(rng.standard_normal((max(n_candidates // 4, k_i), 3)) * sig, -1.0, 1.0)
        existing = np.vstack([X, *picked]) if picked else X
        picked.append(_greedy_farthest(cands / sig, existing / sig, k_i).reshape(-1, 3) * sig)
    cands = sample_focus(rng, max(n_candidates, k), focus_scale, focus_fraction)
    existing = np.vstack([X, *picked]) if picked else X
    picked.append(_greedy_farthest(cands, existing, k - n_q).reshape(-1, 3))
    return np.vstack(picked)


def exploit(rng, model, X, y, k, n_candidates, min_spacing: float = 0.02, query_sigmas=()) -> np.ndarray:
    """Midpoints of pairs of support vectors with opposite labels (each SV with its nearest
    opposite SV). Shortest pairs first, since they straddle the boundary most tightly; with
    query_sigmas, the length is divided by (0.05 + the largest unnormalized query-Gaussian
    density at the midpoint), so the boundary where rho is decided comes first;
    midpoints closer than min_spacing to a sample are skipped; jittered midpoints (spread
    ~ a quarter of the pair length) fill up when there are too few."""
    if k <= 0:
        return np.zeros((0, 3))
    sv = np.asarray(getattr(model, "support_", []), dtype=int)
    pos, neg = sv[y[sv]], sv[~y[sv]]
    if len(pos) == 0 or len(neg) == 0:
        return explore(rng, X, k, n_candidates, 0.25, 0.5)
    P, N = X[pos], X[neg]
    d2 = ((P[:, None, :] - N[None, :, :]) ** 2).sum(-1)
    pairs = {(i, int(np.argmin(d2[i]))) for i in range(len(P))}
    pairs |= {(int(np.argmin(d2[:, j])), j) for j in range(len(N))}
    pairs = sorted(pairs)
    mids = np.array([(P[i] + N[j]) / 2 for i, j in pairs])
    key = np.sqrt(np.array([d2[ij] for ij in pairs]))
    if len(query_sigmas):
        dens = np.max([np.exp(-0.5 * ((mids / np.asarray(sg)) ** 2).sum(1)) for sg in query_sigmas], axis=0)
        key = key / (0.05 + dens)
    order = np.argsort(key, kind="stable")
    pairs, mids = [pairs[o] for o in order], mids[order]
    lens = np.sqrt(np.array([d2[ij] for ij in pairs]))
    picked = []
    existing = X
    for m in mids:
        if _nearest_dist(m[None], existing)[0] >= min_spacing:
            picked.append(m)
            existing = np.vstack([existing, m])
            if len(picked) == k:
                return np.asarray(picked)
    need = k - len(picked)
    src = rng.integers(0, len(mids), size=need)
    jit = mids[src] + rng.normal(size=(need, 3)) * (0.25 * lens[src] + 0.01)[:, None]
    return np.vstack([np.asarray(picked).reshape(-1, 3), np.clip(jit, -1.0, 1.0)])


def _allocate(k: int, weights) -> np.ndarray:
    """k samples split across the query levels in proportion to weights (+ 1e-3, so a
    settled level still gets a share), remainders to the largest weights."""
    w = np.asarray(weights, float) + 1e-3
    alloc = np.floor(k * w / w.sum()).astype(int)
    for i in np.argsort(-w, kind="stable")[: k - alloc.sum()]:
        alloc[i] += 1
    return alloc


def _pick_spaced(C, score, sg, existing, k, min_spacing, keep_zero=False) -> list:
    """Greedy, best score first: up to k candidates C, no two picks (or a pick and an
    existing sample) closer than min_spacing in the Gaussian's sigma units sg; stops at a
    non-positive score (a zero score is still taken with keep_zero)."""
    score = np.array(score, float)
    score[_nearest_dist(C / sg, existing / sg) < min_spacing] = -1.0
    picked = []
    for _ in range(k):
        i = int(np.argmax(score))
        if score[i] < 0 or (score[i] == 0 and not keep_zero):
            break
        picked.append(C[i][None])
        score[np.sqrt((((C - C[i]) / sg) ** 2).sum(axis=1)) < min_spacing] = -1.0
    return picked


def _candidates(rng, sg, n) -> np.ndarray:
    return np.clip(rng.standard_normal((n, 3)) * sg, -1.0, 1.0)


def exploit_rho(rng, cal, query_sigmas, se, X, k, n_candidates, min_spacing: float = 0.5) -> np.ndarray:
    """Query-by-committee for rho: candidates from each query Gaussian N(0, sigma), scored by
    the spread (standard deviation) of P(success) over the k fold classifiers of the
    calibration, i.e. by their share of rho's jackknife variance; the levels get samples in
    proportion to their jackknife se. Greedy: best score first, no two picks (or a pick and
    an existing sample) closer than min_spacing in that Gaussian's sigma units. The SV
    midpoints refine the boundary everywhere; these refine it where rho is undecided."""
    if k <= 0 or not cal.fold_models or not len(query_sigmas):
        return np.zeros((0, 3))
    picked = []
    for sg, k_l in zip(query_sigmas, _allocate(k, se)):
        if k_l <= 0:
            continue
        sg = np.asarray(sg, float)
        C = _candidates(rng, sg, max(n_candidates // 2, k_l))
        score = np.std([cal.probability(C, m, sg) for m in cal.fold_models], axis=0)
        picked += _pick_spaced(C, score, sg, np.vstack([X, *picked]), k_l, min_spacing, keep_zero=True)
    return np.vstack(picked) if picked else np.zeros((0, 3))


def exploit_band(rng, cal, query_sigmas, X, k, n_candidates, min_spacing: float = 0.5) -> np.ndarray:
    """Uncertainty sampling weighted by each query Gaussian: candidates from N(0, sigma),
    scored by p (1 - p) of the calibrated success probability, so the picks lie on the
    stretch of the GSB that carries that Gaussian's mass. A small sigma's Gaussian covers a
    region a few millimetres wide where rho moves by tens of percent per millimetre of
    boundary shift; the boundary-wide exploitation rarely lands there. The levels get
    samples in proportion to their band mass E[p (1 - p)]; greedy picks as in exploit_rho."""
    if k <= 0 or cal is None or not len(query_sigmas):
        return np.zeros((0, 3))
    sigmas = [np.asarray(sg, float) for sg in query_sigmas]
    cands = [_candidates(rng, sg, max(n_candidates // 2, k)) for sg in sigmas]
    scores = []
    for sg, C in zip(sigmas, cands):
        p = cal.probability(C, sigma=sg)
        scores.append(p * (1.0 - p))
    picked = []
    for sg, C, score, k_l in zip(sigmas, cands, scores, _allocate(k, [s.mean() for s in scores])):
        if k_l > 0:
            picked += _pick_spaced(C, score, sg, np.vstack([X, *picked]), k_l, min_spacing)
    return np.vstack(picked) if picked else np.zeros((0, 3))


def exploit_gp(rng, gp, query_sigmas, se, X, k, n_candidates, min_spacing: float = 0.5) -> np.ndarray:
    """Samples where rho is undecided on the GP (gpc.GPSuccessModel): candidates from each
    query Gaussian N(0, sigma), scored by the posterior variance of P(success), so they land
    on the stretch of the boundary that carries the Gaussian's mass and is least pinned
    down. The levels get samples in proportion to their rho posterior standard deviation;
    greedy picks as in exploit_rho."""
    if k <= 0 or gp is None or gp.constant is not None or not len(query_sigmas):
        return np.zeros((0, 3))
    picked = []
    for sg, k_l in zip(query_sigmas, _allocate(k, se)):
        if k_l <= 0:
            continue
        sg = np.asarray(sg, float)
        C = _candidates(rng, sg, max(n_candidates // 2, k_l))
        picked += _pick_spaced(C, gp.probability_variance(C), sg, np.vstack([X, *picked]), k_l, min_spacing)
    return np.vstack(picked) if picked else np.zeros((0, 3))
