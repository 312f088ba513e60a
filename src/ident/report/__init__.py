"""Reports: Markdown + self-contained HTML with embedded figures, JSON and CSV.

``html`` (Markdown subset -> one HTML file, PNG inlined), ``plots`` (matplotlib figures as PNG
bytes), ``run_report`` (the report of an ``ident run`` folder). Only this layer, the CLI and
the replay writer write files. Import the submodules directly.
"""
