"""``python -m app``: the command line of app/cli/main.py, its exit status the process's."""
from app.cli.main import main

raise SystemExit(main())
