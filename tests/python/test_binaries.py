"""The built FMU archives and their binaries (dist/*.fmu), as an importer sees them.

- Each archive holds exactly modelDescription.xml, binaries/linux64/<id>.so (no
  ``lib`` prefix: FMI 2.0 §2.4 names the binary after the modelIdentifier) and
  documentation/index.html, and the XML's modelIdentifier is <id>.
- Each binary exports all 34 functions of the FMI 2.0 common and
  co-simulation API, and fmi2GetVersion / fmi2GetTypesPlatform answer "2.0"
  and "default".
- Every shipped scene's FMU is checked (issue 6); the passive 1D scene's
  binary has no CE-SEE solve in it.
- HillMuscle1D's binary is built without the ``fe`` Cargo feature (fmu_build:
  ``--no-default-features --features export-scene``): its symbol table
  names nothing from ``hill_muscle::fe``, ``hill_muscle::fmus::hillfe`` or
  faer, while HillMuscleFE's does (so the check can fail), and it is several
  times smaller.

Linux only (binaries/linux64, ELF symbol table read with binutils' ``nm -C``).
"""

from __future__ import annotations

import ctypes
import re
import shutil
import subprocess
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
# Every shipped scene (issue 6): fmu_build/scenes/*.toml, one FMU each.
IDS = sorted(p.stem for p in (REPO / "modelDescription").glob("*.xml"))
ONE_D = [i for i in IDS if i.endswith("1D")]

FMI2_FUNCTIONS = [
    # common
    "fmi2GetTypesPlatform", "fmi2GetVersion", "fmi2SetDebugLogging",
    "fmi2Instantiate", "fmi2FreeInstance",
    "fmi2SetupExperiment", "fmi2EnterInitializationMode", "fmi2ExitInitializationMode",
    "fmi2Terminate", "fmi2Reset",
    "fmi2GetReal", "fmi2GetInteger", "fmi2GetBoolean", "fmi2GetString",
    "fmi2SetReal", "fmi2SetInteger", "fmi2SetBoolean", "fmi2SetString",
    "fmi2GetFMUstate", "fmi2SetFMUstate", "fmi2FreeFMUstate",
    "fmi2SerializedFMUstateSize", "fmi2SerializeFMUstate", "fmi2DeSerializeFMUstate",
    "fmi2GetDirectionalDerivative",
    # co-simulation
    "fmi2SetRealInputDerivatives", "fmi2GetRealOutputDerivatives",
    "fmi2DoStep", "fmi2CancelStep",
    "fmi2GetStatus", "fmi2GetRealStatus", "fmi2GetIntegerStatus",
    "fmi2GetBooleanStatus", "fmi2GetStringStatus",
]


def test_the_function_list_is_the_fmi2_co_simulation_api():
    assert len(FMI2_FUNCTIONS) == 34
    assert len(set(FMI2_FUNCTIONS)) == 34


def fmu_file(fmu_id: str) -> Path:
    path = REPO / "dist" / f"{fmu_id}.fmu"
    if not path.is_file():
        pytest.fail(f"{path} not found: build the FMUs first with `scripts/build_fmus.sh`",
                    pytrace=False)
    return path


@pytest.fixture(scope="module")
def extracted(tmp_path_factory):
    """FMU id -> (directory the archive was extracted to, its entry names)."""
    out = {}
    for fmu_id in IDS:
        path = fmu_file(fmu_id)
        target = tmp_path_factory.mktemp(fmu_id)
        with zipfile.ZipFile(path) as z:
            names = z.namelist()
            z.extractall(target)
        out[fmu_id] = (target, names)
    return out


def binary(extracted, fmu_id: str) -> Path:
    return extracted[fmu_id][0] / "binaries" / "linux64" / f"{fmu_id}.so"


@pytest.mark.parametrize("fmu_id", IDS)
def test_archive_holds_exactly_the_three_entries(extracted, fmu_id):
    _, names = extracted[fmu_id]
    assert sorted(names) == sorted([
        "modelDescription.xml",
        f"binaries/linux64/{fmu_id}.so",
        "documentation/index.html",
    ])
    assert not any(Path(n).name.startswith("lib") for n in names)


@pytest.mark.parametrize("fmu_id", IDS)
def test_model_identifier_matches_the_binary(extracted, fmu_id):
    root = ET.parse(extracted[fmu_id][0] / "modelDescription.xml").getroot()
    assert root.tag == "fmiModelDescription"
    assert root.get("fmiVersion") == "2.0"
    assert root.get("modelName") == fmu_id
    cs = root.findall("CoSimulation")
    assert len(cs) == 1, "a Co-Simulation FMU"
    assert root.find("ModelExchange") is None
    assert cs[0].get("modelIdentifier") == fmu_id
    assert binary(extracted, fmu_id).is_file()


@pytest.mark.parametrize("fmu_id", IDS)
def test_binary_exports_the_fmi2_co_simulation_api(extracted, fmu_id):
    lib = ctypes.CDLL(str(binary(extracted, fmu_id)))
    missing = [name for name in FMI2_FUNCTIONS if not hasattr(lib, name)]
    assert missing == []
    # The lookup goes to this library, not anything it links: a name it does
    # not define is not found.
    assert not hasattr(lib, "fmi2NotAFunction")

    lib.fmi2GetVersion.restype = ctypes.c_char_p
    lib.fmi2GetVersion.argtypes = []
    lib.fmi2GetTypesPlatform.restype = ctypes.c_char_p
    lib.fmi2GetTypesPlatform.argtypes = []
    assert lib.fmi2GetVersion() == b"2.0"
    assert lib.fmi2GetTypesPlatform() == b"default"


def symbols(path: Path) -> list[str]:
    """Demangled names of the binary's symbol table (.symtab and .dynsym)."""
    nm = shutil.which("nm")
    if nm is None:
        pytest.fail("`nm` (binutils) is needed to read the binaries' symbol tables", pytrace=False)
    names = []
    for extra in ([], ["-D"]):
        proc = subprocess.run([nm, "-C", *extra, str(path)], capture_output=True, text=True,
                              timeout=120)
        assert proc.returncode == 0, proc.stderr
        names += [line.split(" ", 2)[-1] for line in proc.stdout.splitlines() if line.strip()]
    return names


FE_CODE = re.compile(r"\bhill_muscle::fe::|\bhill_muscle::fmus::hillfe::|\bfaer::")


def test_1d_binary_contains_no_fe_code_and_the_fe_binary_does(extracted):
    one_d = symbols(binary(extracted, "HillMuscle1D"))
    fe = symbols(binary(extracted, "HillMuscleFE"))

    # The symbol tables are there (not stripped) and demangled: the law's code
    # is named in both.
    assert any(s.startswith("hill_muscle::law::") for s in one_d)
    assert any(s.startswith("hill_muscle::law::") for s in fe)

    assert [s for s in one_d if FE_CODE.search(s)] == []
    assert any("hill_muscle::fe::" in s for s in fe), "the FE binary names its FE code"
    assert any(re.search(r"\bfaer::", s) for s in fe), "the FE binary names faer"


@pytest.mark.parametrize("fmu_id", [i for i in ONE_D if i != "HillMuscle1D"])
def test_every_1d_scene_binary_contains_no_fe_code(extracted, fmu_id):
    names = symbols(binary(extracted, fmu_id))
    assert any(s.startswith("hill_muscle::law::") for s in names)
    assert [s for s in names if FE_CODE.search(s)] == []


CE_SEE_SOLVE = re.compile(r"\bhill_muscle::law::hill_fibre::step_solve\b")


def test_the_passive_binary_contains_no_ce_see_solve_and_the_full_one_does(extracted):
    """The passive scene has no contractile element: the CE-SEE step solve
    (law::hill_fibre::step_solve and its closures) is not compiled into its
    binary, while the full 1D binary names it (so the check can fail)."""
    full = symbols(binary(extracted, "HillMuscle1D"))
    passive = symbols(binary(extracted, "HillPassive1D"))
    assert any(CE_SEE_SOLVE.search(s) for s in full)
    assert [s for s in passive if CE_SEE_SOLVE.search(s)] == []
    # The passive binary is the smaller one.
    assert binary(extracted, "HillPassive1D").stat().st_size < binary(extracted, "HillMuscle1D").stat().st_size


def test_1d_binary_is_much_smaller_than_the_fe_binary(extracted):
    one_d = binary(extracted, "HillMuscle1D").stat().st_size
    fe = binary(extracted, "HillMuscleFE").stat().st_size
    # Measured: ~0.67 MB against ~3.9 MB.
    assert 3 * one_d < fe, (one_d, fe)
