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
