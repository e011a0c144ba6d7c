"""The GMRF prior of the GP (kernel "gmrf"): block-banded Cholesky and selected inverse, the lattice SPDE
precision, and the GP's posterior against a dense GP with the same prior covariance."""
import numpy as np
import pytest

from swarmfield.regression import banded


def _random_band(rng, nb, w, b):
    """A random SPD matrix with w blocks of size b off the diagonal (dense and block-banded)."""
    n = nb * b
    blk = np.abs(np.subtract.outer(np.arange(n) // b, np.arange(n) // b)) <= w
    d = np.where(blk, rng.normal(size=(n, n)), 0.0)
    d = d + d.T
    d += (1.0 - np.linalg.eigvalsh(d).min()) * np.eye(n)
    return d, banded.from_dense(d, b, w), blk


@pytest.mark.parametrize("nb, w, b", [(9, 3, 5), (6, 2, 7), (4, 3, 3), (1, 3, 4)])
def test_selected_inverse_matches_dense_inverse_within_the_band(nb, w, b):
    rng = np.random.default_rng(nb * 100 + w * 10 + b)
    dense, blocks, inside = _random_band(rng, nb, w, b)
    assert np.array_equal(banded.to_dense(blocks), dense)
    factor = banded.cholesky(blocks)
    assert np.allclose(np.tril(banded.to_dense(factor)), np.linalg.cholesky(dense), atol=1e-12)
    sel = banded.to_dense(banded.selected_inverse(factor))
    inv = np.linalg.inv(dense)
    assert np.max(np.abs(sel - inv)[inside]) < 1e-12 * np.max(np.abs(inv))
    assert np.all(sel[~inside] == 0.0)
    z = rng.normal(size=(nb * b, 2))
    assert np.allclose(banded.solve(factor, z), np.linalg.solve(dense, z), atol=1e-12)
    assert np.allclose(banded.solve(factor, z[:, 0]), np.linalg.solve(dense, z[:, 0]), atol=1e-12)
    assert banded.logdet(factor) == pytest.approx(np.linalg.slogdet(dense)[1], abs=1e-10)


def test_cholesky_of_an_indefinite_band_is_an_error():
    rng = np.random.default_rng(1)
    dense, blocks, _ = _random_band(rng, 5, 2, 3)
    blocks[2, 0] -= 100.0 * np.eye(3)
    with pytest.raises(np.linalg.LinAlgError, match="block 2"):
        banded.cholesky(blocks)
