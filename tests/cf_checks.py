"""The CF checkers and CDO as the tests call them: a checker skips where it is absent, CDO fails
(CI installs it: .ci/run)."""

from __future__ import annotations

import json
import shutil
import subprocess
from importlib import resources

import netCDF4
import pytest

# UGRID's cf_role values, which CF adopted with UGRID in CF-1.11; both checkers know only CF-1.8's
# (timeseries_id, profile_id, trajectory_id) and flag them. Nothing else may be an error.
UGRID_ROLES = ("mesh_topology", "face_node_connectivity")


def ugrid_roles(path) -> dict:
    """{variable: its cf_role} of the variables of ``path`` whose cf_role is UGRID's."""
    with netCDF4.Dataset(path) as nc:
        roles = {name: getattr(var, "cf_role", None) for name, var in nc.variables.items()}
    return {name: role for name, role in roles.items() if role in UGRID_ROLES}


def standard_name_table():
    """The CF standard-name table that compliance-checker ships (CI has no network)."""
    pytest.importorskip("compliance_checker")
    return resources.files("compliance_checker") / "data" / "cf-standard-name-table.xml"


def ncas_cf_errors(path, tmp_path) -> list:
    """The NCAS CF checker's (cfchecker) FATAL and ERROR messages on ``path`` as
    (variable or None, message), less UGRID's cf_role values (``UGRID_ROLES``)."""
    try:
        from cfchecker.cfchecks import CFChecker
    except (ImportError, OSError) as exc:  # cfunits needs the udunits2 C library
        pytest.skip(f"the NCAS CF checker (cfchecker) is not usable here: {exc}")
    table = standard_name_table()
    # the files use no area_type or region: empty tables stand in for the ones it would download
    tables = {}
    for key, root in (("cfAreaTypesXML", "area_type_table"), ("cfRegionNamesXML", "standard_region_list")):
        tables[key] = tmp_path / f"{root}.xml"
        tables[key].write_text(f"<{root}><version_number>0</version_number><date>none</date></{root}>")
    checker = CFChecker(cfStandardNamesXML=str(table), **{k: str(v) for k, v in tables.items()}, silent=True)
    result = checker.checker(str(path))
    roles = ugrid_roles(path)
    errors = [(None, m) for m in result["global"]["FATAL"] + result["global"]["ERROR"]]
    for name, found in result["variables"].items():
        for m in found["FATAL"] + found["ERROR"]:
            if not (name in roles and m == "(9.5): Invalid value for cf_role attribute"):
                errors.append((name, m))
    return errors


def ioos_cf_errors(path, tmp_path) -> list:
    """The IOOS compliance-checker's failed high-priority CF-1.8 messages on ``path``,
    less UGRID's cf_role values (``UGRID_ROLES``)."""
    pytest.importorskip("compliance_checker")
    from compliance_checker.runner import CheckSuite, ComplianceChecker

    CheckSuite.load_all_available_checkers()
    report = tmp_path / "report.json"
    ComplianceChecker.run_checker(str(path), ["cf:1.8"], 0, "normal", output_filename=str(report), output_format="json")
    failed = [
        msg
        for check in json.loads(report.read_text())["cf:1.8"]["high_priorities"]
        if check["value"][0] < check["value"][1]
        for msg in check["msgs"]
    ]
    ugrid = {
        f"{r} is not a valid cf_role value. It must be one of timeseries_id, profile_id, trajectory_id"
        for r in UGRID_ROLES
    }
    return [m for m in failed if m not in ugrid]


def cdo(*args) -> subprocess.CompletedProcess:
    """``cdo -s ARGS`` (not checked: the caller reads its status and output); a test that calls it
    fails where CDO is absent, as CI has it and a skipped test there would check nothing."""
    if shutil.which("cdo") is None:
        pytest.fail("CDO is not installed: apt-get install cdo (CI installs it in .ci/run)")
    return subprocess.run(["cdo", "-s", *map(str, args)], capture_output=True, text=True)
