"""Install-time build of the C kernels (everything else is in pyproject.toml).

Every module that defines ``NAME = CLibrary("<name>", C_SOURCE, ..., _SMOKE, ...)`` with ``C_SOURCE``
(and ``_SMOKE``) as literal strings gets its kernel compiled here, with the same flags, key and smoke
test as :mod:`runtime.cbuild` uses at run time, into ``swarmfield/runtime/_ck_<name>_<key>.so`` with
its SHA-256 beside it.  The step is optional: without a compiler (or if a build fails) the install
succeeds and the package uses its NumPy code (one line at run time).  Editable installs build in place
(next to ``runtime/cbuild.py``).
"""
import ast
import importlib.util
import os
import shutil
import tempfile
from pathlib import Path

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext
from setuptools.command.build_py import build_py

ROOT = Path(__file__).resolve().parent


def _cbuild():
    spec = importlib.util.spec_from_file_location("_swarmfield_cbuild", ROOT / "runtime" / "cbuild.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _package_dirs():
    """The folders of the installed subpackages (pyproject's ``packages``: ``swarmfield.ocp`` is ``ocp/``)."""
    import tomllib
    with open(ROOT / "pyproject.toml", "rb") as fh:
        packages = tomllib.load(fh)["tool"]["setuptools"]["packages"]
    return [ROOT.joinpath(*p.split(".")[1:]) for p in packages if "." in p]


def _kernels():
    """``[(name, source, smoke), ...]`` of every ``CLibrary(...)`` defined with literal strings."""
    found = []
    for path in sorted(p for d in _package_dirs() for p in d.glob("*.py")):
        text = path.read_text(encoding="utf-8")
        if "CLibrary(" not in text:
            continue
        tree = ast.parse(text)
        consts = {t.id: n.value.value for n in tree.body if isinstance(n, ast.Assign)
                  and isinstance(n.value, ast.Constant) and isinstance(n.value.value, str)
                  for t in n.targets if isinstance(t, ast.Name)}
        for node in tree.body:
            call = node.value if isinstance(node, (ast.Assign, ast.AnnAssign)) else None
            if not (isinstance(call, ast.Call) and getattr(call.func, "id", None) == "CLibrary" and len(call.args) >= 4):
                continue
            name, src, smoke = call.args[0], call.args[1], call.args[3]
            if isinstance(name, ast.Constant) and isinstance(src, ast.Name) and src.id in consts:
                smoke_text = consts.get(smoke.id) if isinstance(smoke, ast.Name) else None
                found.append((name.value, consts[src.id], smoke_text))
    return found


class build_kernels(build_ext):
    """Compiles the kernels as plain shared libraries (ctypes), not Python extension modules."""

    def get_ext_filename(self, fullname):
        return os.path.join(*fullname.split(".")) + ".so"

    def build_extension(self, ext):
        out = Path(self.get_ext_fullpath(ext.name))
        out.parent.mkdir(parents=True, exist_ok=True)
        try:
            with tempfile.TemporaryDirectory() as tmp:
                _, lib = CB.build_library(ext.c_source, ext.c_name, Path(tmp), ext.c_attempts, ext.c_smoke)
                shutil.copyfile(lib, out)
                shutil.copyfile(Path(tmp) / "lib.sha256", str(out) + ".sha256")
            os.chmod(out, 0o755)
            os.chmod(str(out) + ".sha256", 0o644)
        except Exception as exc:                  # noqa: BLE001 - optional: the package falls back to NumPy
            for p in (out, Path(str(out) + ".sha256")):
                if p.exists():
                    p.unlink()
            print(f"swarmfield: the {ext.c_name} kernel was not built ({exc}); NumPy code will be used")

    def copy_extensions_to_source(self):
        super().copy_extensions_to_source()
        build_py = self.get_finalized_command("build_py")
        for ext in self.extensions:
            inplace, regular = self._get_inplace_equivalent(build_py, ext)
            if os.path.exists(regular + ".sha256"):
                self.copy_file(regular + ".sha256", inplace + ".sha256", level=self.verbose)

    def get_outputs(self):
        outs = super().get_outputs()
        return outs + [o + ".sha256" for o in outs if o.endswith(".so")]

    def get_output_mapping(self):
        mapping = dict(super().get_output_mapping())
        mapping.update({k + ".sha256": v + ".sha256" for k, v in list(mapping.items()) if k.endswith(".so")})
        return mapping


class build_package(build_py):
    """This file is the build script, not a module of the package."""

    def find_package_modules(self, package, package_dir):
        return [m for m in super().find_package_modules(package, package_dir)
                if not (package == "swarmfield" and m[1] == "setup")]


CB = _cbuild()
EXTENSIONS = []
for _name, _source, _smoke in _kernels():
    _attempts = CB.library_keys(_source)
    _ext = Extension(f"swarmfield.runtime.{CB.installed_name(_name, _attempts[0][0])[:-3]}", sources=[], optional=True)
    _ext.c_name, _ext.c_source, _ext.c_smoke, _ext.c_attempts = _name, _source, _smoke, _attempts
    EXTENSIONS.append(_ext)

setup(ext_modules=EXTENSIONS, cmdclass={"build_ext": build_kernels, "build_py": build_package})
