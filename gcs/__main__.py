from gcs.cli import main

raise SystemExit(main())
