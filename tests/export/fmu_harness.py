"""An FMU driven by hand through FMPy's FMI 2.0 bindings (the FMU tests' master loops)."""

from __future__ import annotations

import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave


class Slave:
    """An FMU instance driven by hand, through FMPy's FMI 2.0 bindings."""

    def __init__(self, path: Path, name: str, start: float = 0.0,
                 stop: float | None = None) -> None:
        self.md = read_model_description(str(path))
        self.dir = extract(str(path))
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.fmu = FMU2Slave(guid=self.md.guid, unzipDirectory=self.dir,
                             modelIdentifier=self.md.coSimulation.modelIdentifier,
                             instanceName=name)
        self.fmu.instantiate()
        self.fmu.setupExperiment(startTime=start, stopTime=stop)
        self.fmu.enterInitializationMode()

    def set(self, **values: float) -> None:
        self.fmu.setReal([self.vr[k] for k in values], list(values.values()))

    def get(self, *names: str) -> list[float]:
        return list(self.fmu.getReal([self.vr[n] for n in names]))

    def close(self) -> None:
        try:
            self.fmu.terminate()
        except Exception:  # noqa: BLE001 - after an error only freeInstance is allowed
            pass
        self.fmu.freeInstance()
        shutil.rmtree(self.dir, ignore_errors=True)


@contextmanager
def slaves(*specs: tuple[Path, str], start: float = 0.0,
           stop: float | None = None) -> Iterator[list[Slave]]:
    made = [Slave(p, n, start, stop) for p, n in specs]
    try:
        yield made
    finally:
        for s in made:
            s.close()
