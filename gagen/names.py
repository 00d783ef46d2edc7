"""The rules for names that reach generated code, file names and labels: the one identifier rule of
gagen (``identifier_problem``), which the spec loaders, the front-end (``gagen.frontend``), the
builder (``gagen.build``) and the backends apply, and the label rule.

A name in generated code (a module, kernel or port name; a C symbol, a Python name, a file name) is a
letter followed by letters, digits and underscores, not a C (C99 to C23), C++ or Python keyword, and
bounded in length: so no name can start with ``_`` (the generated files' own names, ``_gagen_*``,
``_Jax``, and reserved C names), break out of a string or comment, or leave the output folder.

* **Identifiers** (the system name, chain names): the system name names the output folder, the C
  files, the C symbols ``<system>_<kernel>`` and a Python package; a chain name prefixes its kernels'
  names ``<chain>_fk``, ``<chain>_fk_jacobian``, ``<chain>_jacobians`` (Python attributes, C symbols,
  upper-cased size macros). They must be a letter followed by letters and digits, with single
  underscores between them (``arm_0``, not ``arm-0``, ``_arm``, ``arm__0`` or ``arm_``): exactly the
  names that ``gagen.symbolic.flatten.identifier`` leaves unchanged, so no two names map to one
  identifier; not a C (C99 to C23), C++ or Python keyword; at most ``MAX_LENGTH`` characters. This also
  makes ``../x``, absolute paths and quotes impossible in file names and strings.
* **Labels** (joint names, robot labels, configuration names): they appear as row labels
  ``robot/joint`` in headers, comments, docstrings and the manifest. Letters, digits and ``_ . : -``,
  starting with a letter, digit or underscore (every bundled URDF's joint names qualify), at most
  ``MAX_LENGTH`` characters: nothing that can end a comment or string (``*/``, quotes, newlines)
  and no ``/``, which separates the robot from the joint.

Names that break a rule are refused (a ``SpecError`` from the loader), never mapped silently.
"""

from __future__ import annotations

import keyword
import re

MAX_LENGTH = 64
_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]*")
_IDENTIFIER = re.compile(r"[A-Za-z][A-Za-z0-9]*(?:_[A-Za-z0-9]+)*")  # single underscores only
_LABEL = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.:-]*")

def _words(text: str) -> frozenset[str]:
    return frozenset(text.split())


# C99 to C23 keywords (and the compilers' asm, fortran)
C_KEYWORDS = _words("""
    auto break case char const continue default do double else enum extern float for goto if inline int
    long register restrict return short signed sizeof static struct switch typedef union unsigned void
    volatile while _Alignas _Alignof _Atomic _Bool _Complex _Generic _Imaginary _Noreturn _Static_assert
    _Thread_local _Pragma alignas alignof bool constexpr false nullptr static_assert thread_local true
    typeof typeof_unqual _BitInt _Decimal32 _Decimal64 _Decimal128 asm fortran
    """)
# the generated header is included from C++ too (extern "C")
CPP_KEYWORDS = _words("""
    and and_eq bitand bitor catch char8_t char16_t char32_t class compl concept consteval constinit
    const_cast co_await co_return co_yield decltype delete dynamic_cast explicit export friend mutable
    namespace new noexcept not not_eq operator or or_eq private protected public reinterpret_cast
    requires static_cast template this throw try typeid typename using virtual wchar_t xor xor_eq
    """)
PYTHON_KEYWORDS = frozenset(keyword.kwlist)  # soft keywords (match, case, type, _) are valid names
RESERVED_WORDS = C_KEYWORDS | CPP_KEYWORDS | PYTHON_KEYWORDS

# the kernels every system has, and the suffixes of each chain's kernels
# (gagen.apps.cooperative.catalogue.build_kernels)
SYSTEM_KERNELS = ("primitive", "similarity", "similarity_jacobians", "task", "similarity_rate")
CHAIN_KERNEL_SUFFIXES = ("fk", "fk_jacobian", "jacobians")
# the kernels of systems of exactly two chains (gagen.apps.cooperative.dual_task)
DUAL_TASK_KERNELS = ("dual_task", "dual_task_jacobians")

IDENTIFIER_RULE = (f"a letter, then letters, digits and single underscores between them (no '-', no "
                   f"leading, trailing or double '_'), not a C, C++ or Python keyword, at most {MAX_LENGTH} "
                   f"characters")
LABEL_RULE = (f"letters, digits and '_', '.', ':', '-' (starting with a letter, digit or '_'), at most "
              f"{MAX_LENGTH} characters")


def identifier_problem(name: object, *, single_underscores: bool = True,
                       max_length: int | None = MAX_LENGTH) -> str | None:
    """Why ``name`` cannot be written into generated code as is (None when it can): ``"not an
    identifier"``, ``"a C, C++ or Python keyword"`` or its length. By default the spec's form, for
    system and chain names (single underscores between letters and digits, at most ``MAX_LENGTH``);
    ``single_underscores=False`` allows any underscores after the first letter (names a user gives a
    kernel, its arguments and outputs), and ``max_length`` another bound (None: none)."""
    pattern = _IDENTIFIER if single_underscores else _NAME
    if not isinstance(name, str) or not pattern.fullmatch(name):
        return "not an identifier"
    if name in RESERVED_WORDS:
        return "a C, C++ or Python keyword"
    if max_length is not None and len(name) > max_length:
        return f"{len(name)} characters; at most {max_length}"
    return None


def label_problem(name: str) -> str | None:
    """Why ``name`` cannot be a joint name, robot label or configuration name (None when it can)."""
    if not _LABEL.fullmatch(name):
        return "contains characters outside the label set"
    if len(name) > MAX_LENGTH:
        return f"{len(name)} characters; at most {MAX_LENGTH}"
    return None


def suggest_identifier(name: str) -> str:
    """A nearby valid identifier, for error messages ('arm-0' -> 'arm_0')."""
    ident = re.sub(r"[^A-Za-z0-9]+", "_", name).strip("_")[:MAX_LENGTH - 2] or "name"
    ident = ident if ident[0].isalpha() else f"n_{ident}"
    return f"{ident}_x" if ident in RESERVED_WORDS else ident


def chain_kernel_names(chain: str) -> tuple[str, ...]:
    """The kernels named after a chain."""
    return tuple(f"{chain}_{suffix}" for suffix in CHAIN_KERNEL_SUFFIXES)
