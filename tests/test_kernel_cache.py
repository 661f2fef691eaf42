"""The numba kernel cache is keyed on the package's sources (raytrace/cache.py, raytrace/jit.py):
an edit of any file, even one that only holds a callee, moves the cache to a new folder."""
import shutil

from raytrace import cache


def test_the_key_changes_when_any_kernel_file_changes(tmp_path):
    copy = tmp_path / "raytrace"
    shutil.copytree(cache.PACKAGE_DIR, copy, ignore=shutil.ignore_patterns("__pycache__"))
    base = cache.source_key(copy)
    assert base == cache.source_key(cache.PACKAGE_DIR)
    seen = {base}
    for rel in ("media/phase.py", "methods/geometry.py", "media/expint.py", "jit.py"):
        path = copy / rel
        original = path.read_bytes()
        path.write_bytes(original + b"\n# edited\n")
        seen.add(cache.source_key(copy))
        path.write_bytes(original)
        assert cache.source_key(copy) == base
    assert len(seen) == 5  # each edit gave its own key
    (copy / "methods" / "new_method.py").write_text("X = 1\n")
    assert cache.source_key(copy) not in seen  # a new file counts too


def test_the_package_kernels_are_cached_under_the_keyed_folder(tmp_path, monkeypatch):
    from raytrace.media.phase import phase_value
    from raytrace.methods.quadrature import airlight_one

    root = str(cache.kernel_cache_dir())
    assert cache.source_key() in root
    for kernel in (phase_value, airlight_one):
        assert kernel._cache._cache_path.startswith(root), kernel._cache._cache_path
    monkeypatch.setenv("RAYTRACE_CACHE", str(tmp_path))
    assert str(cache.kernel_cache_dir()).startswith(str(tmp_path))
