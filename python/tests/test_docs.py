"""Issue 43: the Python package documents itself. Every public name of exoleg and exoleg.gym has
a docstring that help() shows, every public method and property of the public classes too, and
the type stubs declare every public name with the same parameters."""

import ast
import inspect
import os
import pydoc

import pytest

import exoleg

STUBS = os.path.join(os.path.dirname(exoleg.__file__), "__init__.pyi")


def _public(obj):
    return [n for n in dir(obj) if not n.startswith("_")]


@pytest.mark.parametrize("name", exoleg.__all__)
def test_every_public_name_is_documented(name):
    obj = getattr(exoleg, name)
    doc = inspect.getdoc(obj)
    assert doc and len(doc) > 20, f"exoleg.{name} has no docstring"
    assert doc.splitlines()[0] in pydoc.render_doc(obj, renderer=pydoc.plaintext)
    if inspect.isclass(obj) and not issubclass(obj, BaseException):
        for m in _public(obj):
            assert inspect.getdoc(getattr(obj, m)), f"exoleg.{name}.{m} has no docstring"


def test_gym_is_documented():
    gym = pytest.importorskip("exoleg.gym")
    for name in gym.__all__:
        obj = getattr(gym, name)
        if isinstance(obj, tuple):
            continue
        assert inspect.getdoc(obj), f"exoleg.gym.{name} has no docstring"
        for m in _public(obj) if inspect.isclass(obj) else []:
            if m in ("np_random", "np_random_seed", "unwrapped", "spec", "metadata", "render_mode"):
                continue
            assert inspect.getdoc(getattr(obj, m)), f"exoleg.gym.{name}.{m} has no docstring"


def test_the_stubs_declare_every_public_name_with_its_parameters():
    tree = ast.parse(open(STUBS).read())
    declared = {n.name: n for n in tree.body if isinstance(n, (ast.FunctionDef, ast.ClassDef))}
    for name in exoleg.__all__:
        assert name in declared, f"exoleg.{name} is not in __init__.pyi"
        node, obj = declared[name], getattr(exoleg, name)
        if isinstance(node, ast.FunctionDef):
            a = node.args
            stub = [x.arg for x in a.posonlyargs + a.args + a.kwonlyargs]
            real = list(inspect.signature(obj).parameters)
            assert stub == real, f"exoleg.{name}: stub {stub} != {real}"


def _python_blocks():
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    pages = [os.path.join(root, "README.md")]
    for d, _, files in os.walk(os.path.join(root, "docs", "src")):
        pages += [os.path.join(d, f) for f in sorted(files) if f.endswith(".md")]
    blocks = []
    for page in pages:
        lines = open(page).read().split("\n")
        i = 0
        while i < len(lines):
            if lines[i].strip() == "```python run":
                j = i + 1
                while not lines[j].startswith("```"):
                    j += 1
                blocks.append((f"{os.path.relpath(page, root)}:{i + 1}", "\n".join(lines[i + 1 : j])))
                i = j
            i += 1
    return root, blocks


def test_the_manuals_python_blocks_run(tmp_path, monkeypatch):
    root, blocks = _python_blocks()
    assert blocks, "no block marked python run"
    monkeypatch.chdir(root)
    for where, code in blocks:
        try:
            exec(compile(code, where, "exec"), {})
        except Exception as e:  # noqa: BLE001 - name the block
            raise AssertionError(f"{where}: {e!r}") from e
