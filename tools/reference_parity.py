#!/usr/bin/env python3
"""Scores `splat2tiles validate` on the test data of Cesium's 3D Tiles validator.

Usage: tools/reference_parity.py REFERENCE_CHECKOUT [--bin target/release/splat2tiles]
       [--only SUBSTRING] [--json OUT.json]

REFERENCE_CHECKOUT is a clone of CesiumGS/3d-tiles-validator (nothing of it is in this
repository). Every `it(...)` block of its `specs/**/*Spec.ts` that calls
`Validators.validateTilesetFile("specs/data/...")` and states `result.length` and the
`result.get(i).type` codes is one case; blocks with validation options, or that read packages
or single contents, are counted as skipped. Each case's tileset is validated with
`splat2tiles validate FILE --root REFERENCE_CHECKOUT/specs/data --json`, and our top-level
issues compared with the reference's:
  detection        the reference expects an ERROR: we report one (recall over those cases);
  false positive   the reference expects no ERROR: we report one;
  codes            the same set of top-level codes.
Severities of the reference's codes: the table below (its WARNING and INFO codes; any other
code is an ERROR). Prints a summary per spec file and every disagreement.
"""
import argparse
import json
import pathlib
import re
import subprocess
import sys
from collections import defaultdict

# The reference's codes that are not errors (from its issue definitions).
NOT_ERRORS = {
    "ASSET_VERSION_UNKNOWN": "WARNING",
    "TILE_REFINE_WRONG_CASE": "WARNING",
    "TILE_GEOMETRIC_ERRORS_INCONSISTENT": "WARNING",
    "TEMPLATE_URI_MISSING_VARIABLE_NAME": "WARNING",
    "EXTENSION_USED_BUT_NOT_FOUND": "WARNING",
    "EXTENSION_NOT_SUPPORTED": "WARNING",
    "METADATA_SEMANTIC_UNKNOWN": "WARNING",
    "EXTERNAL_TILESET_VALIDATION_WARNING": "WARNING",
    "CONTENT_VALIDATION_WARNING": "WARNING",
    "TYPE_UNEXPECTED": "WARNING",
    "ARRAY_LENGTH_UNEXPECTED": "WARNING",
    "CONTENT_VALIDATION_INFO": "INFO",
    "EXTERNAL_TILESET_VALIDATION_INFO": "INFO",
}

IT_BLOCK = re.compile(r"\bit\(\s*([\"'`])(.*?)\1\s*,(.*?)\n\s*\}\);", re.S)
CALL = re.compile(r"Validators\.(\w+)\(\s*([\"'])(specs/data/[^\"']+)\2\s*([,)])")
LENGTH = re.compile(r"expect\(\s*result\.length\s*\)\.toEqual\(\s*(\d+)\s*\)")
CODE = re.compile(r"expect\(\s*result\.get\(\s*(\d+)\s*\)\.type\s*\)\.toEqual\(\s*[\"'](\w+)[\"']")


def cases(checkout):
    """Yields (spec file, name, data path, count, {index: code}) or a skip reason."""
    for spec in sorted((checkout / "specs").rglob("*Spec.ts")):
        text = spec.read_text(encoding="utf-8", errors="replace")
        for m in IT_BLOCK.finditer(text):
            name, body = m.group(2), m.group(3)
            call = CALL.search(body)
            length = LENGTH.search(body)
            rel = spec.relative_to(checkout).as_posix()
            if not call or not length:
                continue
            if call.group(1) != "validateTilesetFile" or call.group(4) == ",":
                yield rel, name, None, f"skipped: {call.group(1)} with options or another input"
                continue
            codes = {int(i): c for i, c in CODE.findall(body)}
            yield rel, name, (call.group(3), int(length.group(1)), codes), None


def ours(binary, checkout, data):
    """Our top-level issues (code, severity) for one reference file, or None if unreadable."""
    path = checkout / data
    if not path.is_file():
        return None
    out = subprocess.run(
        [binary, "validate", str(path), "--root", str(checkout / "specs" / "data"), "--json"],
        capture_output=True, timeout=300,
    )
    try:
        report = json.loads(out.stdout)
    except json.JSONDecodeError:
        return [("UNREADABLE_REPORT", "ERROR")]
    return [(i["type"], i["severity"]) for i in report.get("issues", [])]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("checkout", type=pathlib.Path)
    ap.add_argument("--bin", default="target/release/splat2tiles")
    ap.add_argument("--only", default="")
    ap.add_argument("--json", type=pathlib.Path)
    a = ap.parse_args()
    if not (a.checkout / "specs" / "data").is_dir():
        sys.exit(f"{a.checkout}: not a checkout of CesiumGS/3d-tiles-validator (no specs/data)")
    per_spec = defaultdict(lambda: defaultdict(int))
    disagreements, rows = [], []
    for spec, name, case, skip in cases(a.checkout):
        if a.only and a.only not in name:
            continue
        s = per_spec[spec]
        if skip:
            s["skipped"] += 1
            continue
        data, count, codes = case
        got = ours(a.bin, a.checkout, data)
        if got is None:
            s["missing data"] += 1
            continue
        expected = [codes.get(i, "?") for i in range(count)]
        expects_error = any(
            c != "?" and NOT_ERRORS.get(c, "ERROR") == "ERROR" for c in expected
        )
        we_error = any(sev == "ERROR" for _, sev in got)
        same_codes = {c for c in expected if c != "?"} == {c for c, _ in got} and "?" not in expected
        s["cases"] += 1
        if expects_error:
            s["expect error"] += 1
            s["detected"] += we_error
        elif count == 0 or all(c != "?" for c in expected):
            s["expect no error"] += 1
            s["false positives"] += we_error
        s["same codes"] += same_codes
        row = {"spec": spec, "case": name, "data": data, "expected": expected,
               "ours": [c for c, _ in got], "detected": we_error if expects_error else None,
               "false_positive": we_error if not expects_error else None}
        rows.append(row)
        if (expects_error and not we_error) or (not expects_error and we_error) or not same_codes:
            disagreements.append(row)
    total = defaultdict(int)
    for spec, s in sorted(per_spec.items()):
        print(f"{spec}: " + ", ".join(f"{k} {v}" for k, v in s.items()))
        for k, v in s.items():
            total[k] += v
    recall = total["detected"] / total["expect error"] if total["expect error"] else float("nan")
    print(f"\nall: {dict(total)}")
    print(f"recall {total['detected']}/{total['expect error']} = {recall:.3f}; "
          f"false positives {total['false positives']}/{total['expect no error']}; "
          f"same top-level codes {total['same codes']}/{total['cases']}")
    print("\ndisagreements (missed error / false positive / other codes):")
    for r in disagreements:
        print(f"  {r['data']}: reference {r['expected']} ours {r['ours']}")
    if a.json:
        a.json.write_text(json.dumps({"total": total, "cases": rows}, indent=1))


if __name__ == "__main__":
    main()
