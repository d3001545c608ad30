"""ferrofmm.load / ferrofmm.save: the commands' reader and writer (ferrofmm-io). Every file form
(CSV with or without a header, spaces, tabs, CRLF; .npy float32/float64/complex64/complex128 in
both byte orders and C or Fortran order; raw .f64) reads the numbers written; evaluations on them
match a direct sum; real charges for Helmholtz are complex charges with zero imaginary parts; the
malformed files of the shared table (crates/testing/data/malformed.json) get the messages the
commands print; with the ferrofmm binary built, its output on the same files equals Python's."""

import json
import os
import pathlib
import shutil
import subprocess

import numpy as np
import pytest

import ferrofmm
from conftest import direct


def rel(a, b):
    """Relative L2 error of a against b (real or complex)."""
    return float(np.linalg.norm(np.asarray(a) - b) / np.linalg.norm(b))

HERE = pathlib.Path(__file__).resolve().parent
MALFORMED = HERE.parent.parent / "testing" / "data" / "malformed.json"
N = 200


def f32_exact(a):
    return np.asarray(a, dtype=np.float32).astype(np.float64)


def forms(tmp, stem, a):
    """``a`` ((n,), (n, c) real or (n,) complex) in every form: [(label, path)]."""
    out = []
    two_d = a.reshape(len(a), -1)
    flat_real = two_d.view(np.float64).reshape(len(a), -1) if a.dtype.kind == "c" else two_d
    for label, kw in [
        ("csv-header", dict(delimiter=",", header="h" * flat_real.shape[1], comments="")),
        ("csv-spaces", dict(delimiter=" ")),
        ("csv-tabs", dict(delimiter="\t")),
        ("csv-crlf", dict(delimiter=",", newline="\r\n")),
    ]:
        p = tmp / f"{stem}-{label}.csv"
        np.savetxt(p, flat_real, fmt="%.17g", **kw)
        out.append((label, p))
    kinds = ["f8", "f4"] if a.dtype.kind == "f" else ["c16", "c8"]
    for code in kinds:
        for order in "<>":
            for fortran in (False, True):
                arr = (two_d if fortran else a).astype(order + code)
                arr = np.asfortranarray(arr) if fortran else np.ascontiguousarray(arr)
                label = f"npy-{order}{code}-{'f' if fortran else 'c'}"
                p = tmp / f"{stem}-{label}.npy"
                np.save(p, arr)
                out.append((label, p))
    p = tmp / f"{stem}-raw.f64"
    flat_real.astype("<f8").tofile(p)
    out.append(("raw", p))
    return out


def test_load_reads_every_form_exactly(tmp_path, rng):
    x = f32_exact(rng.random((N, 3)))
    q = f32_exact(rng.random(N) - 0.5)
    z = f32_exact(rng.random(N) - 0.5) + 1j * f32_exact(rng.random(N) - 0.5)
    for label, p in forms(tmp_path, "p", x):
        got = ferrofmm.load(p)
        assert got.dtype == np.float64 and got.shape == (N, 3), label
        np.testing.assert_array_equal(got, x, err_msg=label)
        np.testing.assert_array_equal(ferrofmm.load(str(p), "points"), x, err_msg=label)
    for label, p in forms(tmp_path, "q", q):
        np.testing.assert_array_equal(ferrofmm.load(p, "charges"), q, err_msg=label)
        got = ferrofmm.load(p, "charges", kernel="helmholtz")
        if label == "raw":
            # Raw .f64 has no shape: a complex kernel's records are re, im pairs.
            np.testing.assert_array_equal(got, q[0::2] + 1j * q[1::2])
            continue
        # Real charges for a complex kernel: zero imaginary parts.
        assert got.dtype == np.complex128 and got.shape == (N,), label
        np.testing.assert_array_equal(got, q + 0j, err_msg=label)
    for label, p in forms(tmp_path, "z", z):
        got = ferrofmm.load(p, "charges", kernel="helmholtz")
        assert got.dtype == np.complex128 and got.shape == (N,), label
        np.testing.assert_array_equal(got, z, err_msg=label)
    d = f32_exact(rng.random((N, 3)))
    np.save(tmp_path / "d.npy", d.astype(np.complex64))
    np.testing.assert_array_equal(
        ferrofmm.load(tmp_path / "d.npy", "dipoles", kernel="helmholtz"), d + 0j
    )
    q[:6].astype("<f8").tofile(tmp_path / "d.f64")
    np.testing.assert_array_equal(ferrofmm.load(tmp_path / "d.f64", "dipoles"), q[:6].reshape(2, 3))


def helmholtz_direct(x, q, k):
    d = np.linalg.norm(x[:, None, :] - x[None, :, :], axis=-1)
    np.fill_diagonal(d, 1.0)
    g = np.exp(1j * k * d) / (4 * np.pi * d)
    np.fill_diagonal(g, 0.0)
    return g @ q


def test_evaluations_on_loaded_files_match_direct_sums(tmp_path, rng):
    x = rng.random((N, 3))
    q = rng.random(N) - 0.5
    z = q + 1j * (rng.random(N) - 0.5)
    np.save(tmp_path / "x.npy", np.asfortranarray(x.astype(">f8")))
    np.savetxt(tmp_path / "q.csv", q, fmt="%.17g", header="charge", comments="")
    np.save(tmp_path / "z.npy", z.astype(">c16"))
    xl = ferrofmm.load(tmp_path / "x.npy")
    r = ferrofmm.laplace(xl, ferrofmm.load(tmp_path / "q.csv", "charges"), eps=1e-8)
    assert rel(r.potential, direct(x, q, x)) < 1e-6
    # Complex charges: complex results; real charges: zero imaginary parts.
    zl = ferrofmm.load(tmp_path / "z.npy", "charges", kernel="helmholtz")
    rz = ferrofmm.helmholtz(xl, zl, k=2.0, eps=1e-8)
    assert rz.potential.dtype == np.complex128
    assert rel(rz.potential, helmholtz_direct(x, z, 2.0)) < 1e-6
    qz = ferrofmm.load(tmp_path / "q.csv", "charges", kernel="helmholtz")
    real = ferrofmm.helmholtz(xl, q, k=2.0, eps=1e-8).potential
    assert rel(real, helmholtz_direct(x, q + 0j, 2.0)) < 1e-6
    assert rel(ferrofmm.helmholtz(xl, qz, k=2.0, eps=1e-8).potential, real) < 1e-12
    fmm = ferrofmm.Fmm(xl, kernel="helmholtz", k=2.0, eps=1e-8)
    assert rel(fmm.evaluate(q).potential, fmm.evaluate(q + 0j).potential) == 0.0


def npy_bytes(descr, fortran, shape, data_bytes):
    """A .npy file as crates/testing/src/files.rs writes the shared cases."""
    shape_text = f"({shape[0]},)" if len(shape) == 1 else "(" + ", ".join(map(str, shape)) + ")"
    d = f"{{'descr': '{descr}', 'fortran_order': {fortran}, 'shape': {shape_text}, }}"
    total = 10 + len(d) + 1
    d += " " * (-total % 64) + "\n"
    return b"\x93NUMPY\x01\x00" + len(d).to_bytes(2, "little") + d.encode() + bytes(data_bytes)


def malformed_cases(tmp):
    for case in json.loads(MALFORMED.read_text()):
        path = tmp / case["name"]
        if "text" in case:
            path.write_bytes(case["text"].encode())
        else:
            npy = case["npy"]
            path.write_bytes(npy_bytes(npy["descr"], npy.get("fortran", False), npy["shape"],
                                       npy["data_bytes"]))
        yield path, case


def test_malformed_files_get_the_commands_messages(tmp_path):
    cases = list(malformed_cases(tmp_path))
    assert len(cases) >= 15
    for path, case in cases:
        kernel = case.get("kernel", "laplace").split(":")[0]
        with pytest.raises(ValueError) as e:
            ferrofmm.load(path, case["what"], kernel=kernel)
        msg = str(e.value)
        assert msg.startswith(str(path)) and case["message"] in msg, (case["name"], msg)


def test_os_errors_and_bad_arguments(tmp_path):
    with pytest.raises(FileNotFoundError, match="No such file"):
        ferrofmm.load(tmp_path / "missing.csv")
    (tmp_path / "d.csv").mkdir()
    with pytest.raises(IsADirectoryError, match="is a directory"):
        ferrofmm.load(tmp_path / "d.csv")
    with pytest.raises(ValueError, match="what must be"):
        ferrofmm.load(tmp_path / "x.csv", "forces")
    with pytest.raises(ValueError, match="unknown kernel"):
        ferrofmm.load(tmp_path / "x.csv", "charges", kernel="coulomb")
    # Stokes dipoles are force dipoles: nine values a row, (n, 3, 3).
    (tmp_path / "force_dipoles.csv").write_text("1,2,3,4,5,6,7,8,9\n9,8,7,6,5,4,3,2,1\n")
    d = ferrofmm.load(tmp_path / "force_dipoles.csv", "dipoles", kernel="stokes")
    assert d.shape == (2, 3, 3) and d[0, 1, 2] == 6.0
    np.save(tmp_path / "three_columns.npy", np.ones((2, 3)))
    with pytest.raises(ValueError, match=r"\(N, 9\) array of dipoles"):
        ferrofmm.load(tmp_path / "three_columns.npy", "dipoles", kernel="stokes")
    with pytest.raises(OSError, match="does not exist"):
        ferrofmm.save(tmp_path / "no" / "o.npy", np.ones(3))
    with pytest.raises(ValueError, match="unknown file type for an output"):
        ferrofmm.save(tmp_path / "o.f64", np.ones(3))
    with pytest.raises(TypeError, match="float64, float32"):
        ferrofmm.save(tmp_path / "o.npy", np.ones(3, dtype=np.int64))
    assert not any(p.name.startswith("o.") for p in tmp_path.iterdir())


def test_save_round_trips_and_writes_results_as_the_command(tmp_path, rng):
    a = rng.random((N, 3))
    for ext in ("csv", "npy"):
        ferrofmm.save(tmp_path / f"a.{ext}", a)
        np.testing.assert_array_equal(ferrofmm.load(tmp_path / f"a.{ext}"), a)
        z = rng.random(N) + 1j * rng.random(N)
        ferrofmm.save(tmp_path / f"z.{ext}", z, names=["charge"])
        np.testing.assert_array_equal(
            ferrofmm.load(tmp_path / f"z.{ext}", "charges", kernel="helmholtz"), z
        )
    assert (tmp_path / "z.csv").read_text().startswith("charge_re,charge_im\n")
    assert np.load(tmp_path / "z.npy").dtype == np.complex128
    np.save(tmp_path / "q32.npy", np.float32(rng.random(N)))
    ferrofmm.save(tmp_path / "o32.npy", ferrofmm.load(tmp_path / "q32.npy", "charges").astype(np.float32))
    assert np.load(tmp_path / "o32.npy").dtype == np.float32

    x = rng.random((N, 3))
    r = ferrofmm.helmholtz(x, rng.random(N) + 1j * rng.random(N), k=2.0, gradient=True, eps=1e-6)
    ferrofmm.save(tmp_path / "r.npy", r)
    ferrofmm.save(tmp_path / "r.csv", r)
    saved = np.load(tmp_path / "r.npy")
    assert saved.dtype == np.complex128 and saved.shape == (N, 4)
    np.testing.assert_array_equal(saved[:, 0], r.potential)
    np.testing.assert_array_equal(saved[:, 1:], r.gradient)
    assert (tmp_path / "r.csv").read_text().startswith(
        "potential_re,potential_im,grad_x_re,grad_x_im,grad_y_re,"
    )
    s = ferrofmm.stokes(x, rng.random((N, 3)), gradient=True, eps=1e-6)
    ferrofmm.save(tmp_path / "s.npy", s)
    saved = np.load(tmp_path / "s.npy")
    assert saved.shape == (N, 12)
    # grad_c_a = d u_a / d x_c = gradient[a, c]
    np.testing.assert_array_equal(saved[:, 3:].reshape(N, 3, 3), np.swapaxes(s.gradient, 1, 2))
    batched = ferrofmm.laplace(x, rng.random((2, N)), eps=1e-6)
    with pytest.raises(ValueError, match="one result at a time"):
        ferrofmm.save(tmp_path / "b.npy", batched)


def _ferrofmm_binary():
    """The ferrofmm command built by cargo, if it is."""
    candidates = [os.environ.get("FERROFMM_CLI")]
    for root in (os.environ.get("CARGO_TARGET_DIR"), HERE.parent.parent.parent / "target"):
        if root:
            candidates += [pathlib.Path(root) / p / "ferrofmm" for p in ("debug", "release")]
    candidates.append(shutil.which("ferrofmm"))
    return next((str(c) for c in candidates if c and os.access(c, os.X_OK)), None)


@pytest.mark.skipif(_ferrofmm_binary() is None, reason="the ferrofmm binary is not built")
def test_the_command_and_python_agree_on_the_same_files(tmp_path, rng):
    exe = _ferrofmm_binary()
    x = rng.random((N, 3))
    z = rng.random(N) - 0.5 + 1j * (rng.random(N) - 0.5)
    np.save(tmp_path / "x.npy", np.asfortranarray(x.astype(">f4")))
    np.save(tmp_path / "z.npy", np.asfortranarray(z.astype(">c8").reshape(N, 1)))
    for kernel, k, charges in (("laplace", None, None), ("helmholtz", 2.0, "z.npy")):
        if charges is None:
            np.savetxt(tmp_path / "q.csv", z.real, fmt="%.17g", delimiter=",", newline="\r\n")
            charges = "q.csv"
        spec = kernel if k is None else f"{kernel}:{k}"
        out = tmp_path / f"{kernel}.npy"
        run = subprocess.run(
            [exe, "eval", "--sources", str(tmp_path / "x.npy"), "--charges", str(tmp_path / charges),
             "--kernel", spec, "--order", "6", "--leaf-size", "40", "--scheme", "fft",
             "--gradients", "--out", str(out)],
            capture_output=True, text=True,
        )
        assert run.returncode == 0, run.stderr
        fmm = ferrofmm.Fmm(ferrofmm.load(tmp_path / "x.npy"), kernel=kernel, k=k, order=6,
                           leaf_size=40, scheme="fft", gradient=True)
        r = fmm.evaluate(ferrofmm.load(tmp_path / charges, "charges", kernel=kernel))
        ferrofmm.save(tmp_path / f"py-{kernel}.npy", r)
        cli, py = np.load(out), np.load(tmp_path / f"py-{kernel}.npy")
        assert cli.dtype == py.dtype and cli.shape == py.shape, (cli.dtype, py.dtype)
        assert rel(py, cli) < 1e-12
        # The same malformed file: the same message from both.
        bad = tmp_path / "bad.csv"
        bad.write_text("1,2,3\n4,5\n")
        run = subprocess.run(
            [exe, "eval", "--sources", str(bad), "--charges", str(tmp_path / charges),
             "--kernel", spec, "--out", str(out)], capture_output=True, text=True,
        )
        with pytest.raises(ValueError) as e:
            ferrofmm.load(bad)
        assert run.stderr.strip() == f"error: {e.value}"
