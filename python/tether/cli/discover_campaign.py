"""tether discover A.csv B.csv ...: one discovery over a campaign of records of one tether
(discover.campaign, docs/campaign-discovery.md)."""

from __future__ import annotations


def run_campaign(args, mass_band) -> int:
    """Every record and output checked before any fit (exit 2, one line naming the file); the
    campaign discovered with progress on stderr; OUT.json (and the report) written; the account on
    stdout; each contradicting record named on stderr."""
    from ..discover import DEFAULT_BUDGET, DiscoveryError
    from ..discover.campaign import CampaignInputError, check_campaign, discover_campaign
    from ..discover.campaign_document import campaign_account, campaign_document
    from ..models import parse_model
    from ..report import write_json_atomic
    from . import CLIError, RUN_ERROR
    from .common import check_output_path, check_report_dir, read_checked_trace
    from .console import Progress, warn

    traces = [read_checked_trace(p) for p in [args.trace, *args.more]]
    try:
        check_campaign(traces)
    except CampaignInputError as e:
        raise CLIError(str(e)) from None
    for tr in traces:
        parse_model(args.start, tr.experiment)               # a bad model string fails before any fit
        out = check_output_path(args.json, tr, option="--json")
    report = check_report_dir(args.report)
    budget = DEFAULT_BUDGET if args.budget is None else args.budget
    with Progress("discover", budget, unit="s", deadline=True) as bar:
        try:
            d = discover_campaign(traces, start=args.start, progress=bar.line, budget=budget, mass_band=mass_band,
                                  free_nuisance=args.nuisance)
        except CampaignInputError as e:
            raise CLIError(str(e)) from None
        except DiscoveryError as e:
            raise CLIError(str(e), RUN_ERROR) from None
        except RuntimeError as e:
            raise CLIError(f"the campaign discovery failed: {e}", RUN_ERROR) from None
    doc = campaign_document(d)
    write_json_atomic(out, doc)
    if report is not None:
        from ..campaign_report import write_campaign_report

        write_campaign_report(report, d, doc)
    for c in d.contradicting:
        warn(f"{c['trace']}: contradicts the other records: {c['why']}")
    print(campaign_account(d))
    if report is not None:
        print(f"report: {report / 'index.html'}")
    print(f"record: {out} (also a --params file of the discovered model)")
    return 0
