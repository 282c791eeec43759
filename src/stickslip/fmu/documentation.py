"""The FMUs' ``documentation/`` folder, generated when an FMU is built: ``index.html`` (what the model is, every
variable with its type, default, unit, allowed range and meaning, the laws a selector offers with their
formulas, where the binaries come from, and the licences) and the licence texts in ``licenses/``.

Everything in the page comes from the FMU's completed model description (which the builders write from the
variable table, ``fmu_src/block_interface.py``) and from the licence files of the installed distributions whose
code the FMU carries (:data:`CARRIED`). The page is written the same way from the same inputs: the builds stay
reproducible.
"""

import html
import importlib.metadata
import importlib.util
from xml.etree import ElementTree as ET

from .compile_runtime import MYPY_LICENSE, PREBUILT

#: what separates a variable's meaning from its allowed range in its description (as in the FMU's error messages)
RANGE_MARK = "; allowed: a finite value in "
INDEX = "documentation/index.html"
LICENSES = "documentation/licenses"
#: distribution: (its licence as the page names it, what of it an FMU carries)
CARRIED = {
    "stickslip": ("MIT", "the model: the runtime (resources/sbf_runtime_*), the slave (resources/sbf_slave_*) and "
                         "the C loader that is the FMU's Linux and Windows binaries"),
    "pythonfmu": ("MIT", "PythonFMU 0.7: its Python package (resources/pythonfmu.zip) and its binaries, which the "
                         "loader forwards to (binaries/linux64/*_pythonfmu.so, binaries/win64/*_pythonfmu.dll)"),
    "pythonfmu3": ("MIT", "pythonfmu3: its Python package (resources/pythonfmu3.zip) and its binaries, which the "
                          "loader forwards to (binaries/x86_64-linux/*_pythonfmu.so, "
                          "binaries/x86_64-windows/*_pythonfmu.dll; for aarch64 Linux, and x86_64 Linux hosts on "
                          "which the first does not load, python/lib/libpythonfmu3-export.so in the packed CPythons "
                          "of extra/stickslip/, built from its C++ sources when the FMU is built)"),
    "mypy": ("MIT, with parts of mypyc's C runtime under the PSF License 2 (CPython's)",
             "mypyc's C runtime, compiled into the runtime's compiled modules (resources/*__mypyc*.so)"),
    "python": ("the PSF License Agreement (CPython's), with the licences of what its Windows build includes",
               "python.org's embeddable CPython for Windows, trimmed (python/ beside the Windows binaries), which "
               "they start where the host process has no Python"),
}
#: where the binaries' sources are: the FMU ships none (``sources/`` would be taken for a source-code FMU, which a
#: Python FMU cannot be: the binaries start the Python that runs the slave)
BINARY_SOURCES = (
    "The FMU ships no sources/ folder: its binaries need the Python of resources/ to do anything. The Linux and "
    "Windows binaries (binaries/*/{model}.so, {model}.dll) are stickslip's C loader, compiled when the FMU is built "
    "(for Windows with MinGW-w64) from runtime.c, fast_path.c, platform_posix.c or platform_windows.c and "
    "fmi{version}_front.c in the stickslip package (stickslip/fmu/loader/; stickslip.fmu.loader.install says how). "
    "It loads the CPython shared library and forwards what it does not answer itself to the FMI library's own "
    "binary ({model}_pythonfmu.so, {model}_pythonfmu.dll), which is {library}'s, built from its C++ sources. The "
    "aarch64 Linux binaries (FMI 3 only), the loader and pythonfmu3's, are cross-compiled with Debian's GCC for "
    "arm64 when the FMU is built, the second from the sources of pythonfmu3's source distribution and packed with "
    "the aarch64 CPython in extra/stickslip/ (stickslip.fmu.bundle.aarch64_binaries).")


def split_description(description):
    """``(meaning, range)`` of a variable's description (range ``""`` if it states none)."""
    meaning, _, allowed = (description or "").partition(RANGE_MARK)
    return meaning, allowed


class LicenseError(RuntimeError):
    """stickslip's own licence file is not in its installed metadata: no FMU is built without it."""


def license_text(distribution):
    """The licence file of the installed ``distribution``, from its metadata (``*.dist-info``; stickslip's is the
    checkout's top-level LICENSE, which pyproject.toml's ``license-files`` puts there); mypy's, if it is not
    installed, the copy beside the runtime compiled with the package; for the other distributions a notice naming
    the licence if none is found. Raises :class:`LicenseError` if stickslip's is missing."""
    if distribution == "mypy" and importlib.util.find_spec("mypy") is None:
        for copy in sorted(PREBUILT.glob(f"*/{MYPY_LICENSE}")):
            return copy.read_text(encoding="utf-8")
    try:
        files = importlib.metadata.distribution(distribution).files or []
    except importlib.metadata.PackageNotFoundError:
        files = []
    for path in sorted(files, key=str):
        if path.name.upper().startswith(("LICENSE", "COPYING")) and "dist-info" in str(path):
            return path.read_text(encoding="utf-8")
    if distribution == "stickslip":
        raise LicenseError("stickslip's licence file (LICENSE) is not in its installed metadata, and every FMU "
                           "carries it: install stickslip (in a checkout: pip install -e .) before building an FMU")
    return (f"{distribution} is licensed under {CARRIED[distribution][0]}; its licence file was not installed where "
            f"this FMU was built. See the {distribution} distribution on https://pypi.org/project/{distribution}/.\n")


def entries(model_description, summary, distributions, selectors=None):
    """The documentation folder's files, ``{archive name: bytes}``: ``model_description`` (the completed XML,
    bytes), ``summary`` (a paragraph on the model, text), ``distributions`` (the :data:`CARRIED` keys whose code
    the FMU carries) and ``selectors``: {variable name: ``(type name, items)``, items ``(code, name, formula)``}
    of the variables that select a law by its code."""
    root = ET.fromstring(model_description)
    files = {f"{LICENSES}/{name}.txt": license_text(name).encode() for name in distributions}
    files[INDEX] = _page(root, summary, distributions, selectors or {}).encode()
    return files


def with_license(page, name):
    """The bytes of the ``index.html`` ``page`` with the licence of the :data:`CARRIED` ``name`` (whose text the FMU
    carries in ``licenses/<name>.txt``) added to its list of licences."""
    item, text = _license_item(name), page.decode()
    return page if item in text else text.replace("</ul>\n</body>", f"{item}</ul>\n</body>", 1).encode()


def _license_item(name):
    return (f"<li><a href=\"licenses/{name}.txt\">{_e(name)}</a>: {_e(CARRIED[name][0])}; in this FMU: "
            f"{_e(CARRIED[name][1])}</li>\n")


def _page(root, summary, distributions, selectors):
    """index.html of the model description ``root``."""
    model, version = root.get("modelName"), root.get("fmiVersion")
    library = "PythonFMU" if version.startswith("2") else "pythonfmu3"
    enumerations = dict(selectors.values())
    parts = [f"<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>{_e(model)}</title>\n"
             f"<style>body{{font-family:sans-serif;max-width:70em}}td,th{{border-bottom:1px solid #ccc;"
             f"padding:2px 6px;text-align:left;vertical-align:top}}</style>\n</head>\n<body>\n",
             f"<h1>{_e(model)}</h1>\n<p>{_e(root.get('description') or '')}. FMI {_e(version)}, built by "
             f"{_e(root.get('generationTool') or 'stickslip')}.</p>\n"
             f"<p>{_e(summary)}</p>\n",
             "<h2>Variables</h2>\n<table>\n<tr><th>name</th><th>causality</th><th>type</th><th>default</th>"
             "<th>unit</th><th>allowed range</th><th>meaning</th></tr>\n",
             *(_row(cells) for cells in _variables(root, selectors)), "</table>\n"]
    if enumerations:
        parts.append("<h2>Laws</h2>\n")
        for name, items in enumerations.items():
            parts.append(f"<h3>{_e(name)}</h3>\n<table>\n<tr><th>code</th><th>name</th><th>formula</th></tr>\n")
            parts += [_row(item) for item in items] + ["</table>\n"]
    sources = BINARY_SOURCES.format(model=model, version=version[0], library=library)
    parts.append(f"<h2>Binaries and sources</h2>\n<p>{_e(sources)}</p>\n")
    parts.append("<h2>Licences</h2>\n<ul>\n")
    parts += [_license_item(name) for name in distributions]
    parts.append("</ul>\n</body>\n</html>\n")
    return "".join(parts)


def with_carried_licenses(entries, licenses, what):
    """Add to an FMU's ``entries`` the licence texts ``licenses`` ({name: bytes}) of what its binaries folder carries
    besides the loader (``what``: where it is, for the page), in ``licenses/`` and as items of index.html's list; a
    text that ``licenses/`` holds already (another platform's build of the same package) is linked there, not copied."""
    if not licenses or INDEX not in entries:
        return
    held = {text: path.rsplit("/", 1)[1] for path, text in entries.items() if path.startswith(f"{LICENSES}/")}
    files = {name: held.get(text, f"{name}.txt") for name, text in licenses.items()}
    items = "".join(f"<li><a href=\"licenses/{files[name]}\">{_e(name)}</a>: "
                    f"{_e('PSF License 2' if name == 'cpython' else 'its Debian package copyright file')}; in this "
                    f"FMU: {_e(what)}</li>\n" for name in sorted(licenses))
    page = entries[INDEX].decode()
    entries[INDEX] = page.replace("</ul>\n</body>", items + "</ul>\n</body>", 1).encode()
    entries.update({f"{LICENSES}/{file}": licenses[name] for name, file in files.items() if file == f"{name}.txt"})


def _variables(root, selectors):
    """One row of cells per model variable: name, causality, type, default, unit, allowed range, meaning."""
    rows = []
    for variable in root.find("ModelVariables"):
        element = variable[0] if variable.tag == "ScalarVariable" else variable
        meaning, allowed = split_description(variable.get("description"))
        if variable.get("name") in selectors:
            allowed = ", ".join(f"{code} {name}" for code, name, _ in selectors[variable.get("name")][1])
        elif not allowed and (element.get("min") or element.get("max")):
            allowed = f"[{element.get('min') or '-inf'}, {element.get('max') or 'inf'}]"
        rows.append((variable.get("name"), variable.get("causality") or "local", element.tag,
                     element.get("start") or "", element.get("unit") or "1", allowed or "any", meaning))
    return rows


def _row(cells):
    return "<tr>" + "".join(f"<td>{_e(str(cell))}</td>" for cell in cells) + "</tr>\n"


def _e(text):
    return html.escape(text, quote=True)
