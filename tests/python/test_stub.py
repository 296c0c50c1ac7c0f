"""Python.TypeStubMatchesThePackage: facemorph/__init__.pyi declares exactly the package's public
names, each function and method with the package's parameters (names, order, kinds, defaults given
or not), and each class with its real bases; so an API change that forgets the stub fails."""

import ast
import inspect
import os
import unittest

import support  # noqa: F401 (the environment)
import facemorph


def stub_tree():
    with open(os.path.join(os.path.dirname(facemorph.__file__), "__init__.pyi")) as f:
        return ast.parse(f.read())


def parameters(node):
    """(name, kind, has default) of an ast function's parameters, self excluded."""
    a = node.args
    out = []
    positional = a.posonlyargs + a.args
    defaults = [None] * (len(positional) - len(a.defaults)) + a.defaults
    for arg, default in zip(positional, defaults):
        kind = "POSITIONAL_ONLY" if arg in a.posonlyargs else "POSITIONAL_OR_KEYWORD"
        out.append((arg.arg, kind, default is not None))
    if a.vararg:
        out.append((a.vararg.arg, "VAR_POSITIONAL", False))
    for arg, default in zip(a.kwonlyargs, a.kw_defaults):
        out.append((arg.arg, "KEYWORD_ONLY", default is not None))
    if a.kwarg:
        out.append((a.kwarg.arg, "VAR_KEYWORD", False))
    return [p for p in out if p[0] != "self"]


def real_parameters(function):
    return [(p.name, p.kind.name, p.default is not inspect.Parameter.empty)
            for p in inspect.signature(function).parameters.values() if p.name != "self"]


class TypeStub(unittest.TestCase):
    def test_the_stub_is_the_package(self):
        tree = stub_tree()
        declared = {}
        for node in tree.body:
            if isinstance(node, (ast.FunctionDef, ast.ClassDef)):
                declared[node.name] = node
            elif isinstance(node, ast.AnnAssign):
                declared[node.target.id] = node
        public = {name for name in declared if not name.startswith("_") or name == "__version__"}
        self.assertEqual(public, set(facemorph.__all__) | {"__version__"})
        for name in public:
            real = getattr(facemorph, name)
            node = declared[name]
            if isinstance(node, ast.FunctionDef):
                self.assertEqual(parameters(node), real_parameters(real), name)
            elif isinstance(node, ast.ClassDef):
                self.assertTrue(inspect.isclass(real), name)
                self.assertEqual([ast.unparse(b) for b in node.bases], [b.__name__ for b in real.__bases__ if b.__name__ not in ("object", "pybind11_object")], name)
                for member in node.body:
                    if not isinstance(member, ast.FunctionDef):
                        continue
                    self.assertTrue(hasattr(real, member.name), f"{name}.{member.name}")
                    attribute = inspect.getattr_static(real, member.name)
                    if inspect.isfunction(attribute):  # a Python method: its parameters too
                        self.assertEqual(parameters(member), real_parameters(attribute), f"{name}.{member.name}")


if __name__ == "__main__":
    support.main()
