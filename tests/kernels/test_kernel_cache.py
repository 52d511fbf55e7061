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
    # the kernel plumbing points numba at the folder before it imports numba
    code = ("import json, assistant.kernels.lazy, numba\n"
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


def test_importing_the_package_does_no_work():
    """`import assistant` neither hashes the kernels nor touches numba's setting; the
    Session is there on first use (`from assistant import Session`)."""
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    code = ("import json, os, sys\n"
            "import assistant\n"
            "quiet = [os.environ.get('NUMBA_CACHE_DIR'), 'numba' in sys.modules,\n"
            "         'assistant.kernels.cache' in sys.modules, sorted(m for m in sys.modules\n"
            "         if m.startswith('assistant.'))]\n"
            "from assistant import Session\n"
            "from assistant.session.session import Session as S\n"
            "print(json.dumps([quiet, Session is S, assistant.Session is S]))\n")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                         text=True, timeout=120, check=True)
    quiet, same, attr = json.loads(out.stdout.strip().splitlines()[-1])
    assert quiet == [None, False, False, []]
    assert same and attr
