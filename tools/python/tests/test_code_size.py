"""Issue 28: every Python file in tools/python has one job and stays readable: no file
over 500 lines, no function (methods and nested functions included) over 80."""

import ast
import os

from conftest import PYROOT

MAX_FILE_LINES = 500
MAX_FUNCTION_LINES = 80


def python_files():
    for root, dirs, files in os.walk(PYROOT):
        dirs[:] = [d for d in dirs if not d.startswith((".", "__pycache__"))]
        for name in files:
            if name.endswith(".py"):
                yield os.path.join(root, name)


def test_the_limits_see_every_python_file():
    names = {os.path.relpath(p, PYROOT) for p in python_files()}
    # premise: the walk reaches the SDK, the CLI, the studio and the tests
    assert {"servobus/bus.py", "servobus/cli/__init__.py", "servobus/studio/server.py",
            "tests/test_code_size.py"} <= names, sorted(names)


def test_no_python_file_is_over_500_lines():
    long = {}
    for path in python_files():
        with open(path, encoding="utf-8") as f:
            n = sum(1 for _ in f)
        if n > MAX_FILE_LINES:
            long[os.path.relpath(path, PYROOT)] = n
    assert not long, "split these by job (at most %d lines): %s" % (MAX_FILE_LINES, long)


def test_no_function_is_over_80_lines():
    long = {}
    for path in python_files():
        with open(path, encoding="utf-8") as f:
            tree = ast.parse(f.read(), path)
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = node.end_lineno - node.lineno + 1
                if n > MAX_FUNCTION_LINES:
                    long["%s:%d %s" % (os.path.relpath(path, PYROOT), node.lineno,
                                       node.name)] = n
    assert not long, "shorten these (at most %d lines): %s" % (MAX_FUNCTION_LINES, long)
