"""results.csv / results.parquet (one row per mission) and primitives.csv (one row per primitive)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

PRIMITIVE_COLUMNS = ("mission_id", "family", "step", "kind", "action", "entities", "ok", "seconds", "time_limit",
                     "m_true", "m_hat", "alpha_true", "alpha_hat")


def primitives_table(rows: list[dict]):
    """primitives.csv: the primitive records of every finished mission, with its id and family."""
    import pandas as pd

    recs = [{"mission_id": r["mission_id"], "family": r["family"], **p}
            for r in rows for p in r.get("primitives") or ()]
    return pd.DataFrame(recs, columns=list(PRIMITIVE_COLUMNS))


def write_results(df, out: Path) -> list[Path]:
    """results.csv, and results.parquet when pyarrow is installed."""
    written = [out / "results.csv"]
    df.to_csv(out / "results.csv", index=False, float_format="%.10g")
    if importlib.util.find_spec("pyarrow") is None:
        return written
    df.to_parquet(out / "results.parquet", index=False, engine="pyarrow")
    written.append(out / "results.parquet")
    return written
