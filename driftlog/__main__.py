from driftlog.cli import main

raise SystemExit(main())
