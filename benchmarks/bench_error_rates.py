"""Error rates of adaptive campaigns' decisions on synthetic streams of known means.

2000 simulated campaigns per setting (α = 5 %, looks every 32 runs up to 1000; the family
setting up to 400), with the bounds, levels and decision rules a campaign uses
(idefix_rules/campaign/statistics/error_rates.py): the share that decided wrongly, the share that
decided before the cap, and the runs they used. The last line is the family setting with every bound
at α instead of the campaign's α budget: what the budget prevents. The same numbers are
asserted by tests/campaign/test_campaign_error_rates.py and copied into
docs/campaign-format.md ("How α is spent").

    python benchmarks/bench_error_rates.py [--replications 2000] [--markdown]
"""

from __future__ import annotations

import argparse
import time

from idefix_rules.campaign.statistics import error_rates


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--replications", type=int, default=2000)
    parser.add_argument("--markdown", action="store_true", help="print a Markdown table")
    args = parser.parse_args()
    started = time.perf_counter()
    rows = error_rates.table(args.replications)
    contrast = error_rates.unspent(args.replications)
    seconds = time.perf_counter() - started
    tolerance = error_rates.tolerance(args.replications)
    if args.markdown:
        print(error_rates.markdown(rows))
        print()
        print(error_rates.markdown([contrast]))
    else:
        cells = [error_rates.HEADER, *(row.cells() for row in rows), contrast.cells()]
        widths = [max(len(line[column]) for line in cells) for column in range(len(cells[0]))]
        for position, line in enumerate(cells):
            if position in (1, len(cells) - 1):
                print("  ".join("-" * width for width in widths))
            print("  ".join(cell.ljust(width) for cell, width in zip(line, widths, strict=True)))
    print(f"\nα = {error_rates.ALPHA}, {args.replications} campaigns per setting; every wrong "
          f"rate of the campaign's budget must stay below α + {tolerance:.4f} (3 standard "
          f"errors); {seconds:.1f} s")


if __name__ == "__main__":
    main()
