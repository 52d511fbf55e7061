"""The numba cache folder follows the kernels' sources: any change to a kernel module gives
a new folder (numba alone would keep a caller compiled against an old callee), other
modules do not, and NUMBA_CACHE_DIR still wins."""

from __future__ import annotations

import json
import os
import subprocess
import sys

from assistant.kernels.cache import kernel_source_hash


def test_hash_follows_kernel_modules_only(tmp_path):
    (tmp_path / "sub").mkdir()
    kernel = tmp_path / "sub" / "k.py"
    kernel.write_text("from numba import njit\n@njit\ndef f(x):\n    return x\n")
    plain = tmp_path / "plain.py"
    plain.write_text("X = 1\n")
    h0 = kernel_source_hash(tmp_path)
    plain.write_text("X = 2\n")
    assert kernel_source_hash(tmp_path) == h0
    kernel.write_text("from numba import njit\n@njit\ndef f(x):\n    return x + 1\n")
    h1 = kernel_source_hash(tmp_path)
    assert h1 != h0
    kernel.rename(tmp_path / "sub" / "k2.py")  # where a kernel lives is part of it
    assert kernel_source_hash(tmp_path) != h1


def _cache_dir_in_fresh_process(env: dict) -> str:
    code = ("import json, assistant, numba\n"
            "print(json.dumps(numba.config.CACHE_DIR))\n")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                         text=True, timeout=120, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_numba_caches_under_the_source_hash_unless_told_otherwise(tmp_path):
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    env["CELLTEACH_CACHE"] = str(tmp_path / "home")
    got = _cache_dir_in_fresh_process(env)
    assert got == str(tmp_path / "home" / "numba" / kernel_source_hash())
    env["NUMBA_CACHE_DIR"] = str(tmp_path / "mine")
    assert _cache_dir_in_fresh_process(env) == str(tmp_path / "mine")
