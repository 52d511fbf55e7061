"""`python -m assistant` is the `cellteach` command."""

from assistant.cli import main

raise SystemExit(main())
