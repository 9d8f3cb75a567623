"""The example notebook runs from top to bottom (nbclient), so that it cannot rot (issue 22)."""
from pathlib import Path

import nbformat
from nbclient import NotebookClient


def test_weibull_notebook_runs(root):
    path = root / "examples" / "weibull_montecarlo.ipynb"
    nb = nbformat.read(path, as_version=4)
    NotebookClient(nb, timeout=300, kernel_name="python3", resources={"metadata": {"path": str(path.parent)}}).execute()
    outputs = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])]
    assert not [o for o in outputs if o.output_type == "error"]
    text = "".join(o.get("text", "") for o in outputs if o.output_type == "stream")
    assert "24 tasks, 0 failed" in text and "failure load: mean" in text
    assert any("image/png" in o.get("data", {}) for o in outputs), "the histogram and the specimen are drawn"
