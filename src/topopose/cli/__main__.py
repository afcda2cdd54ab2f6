from topopose.cli.main import main

raise SystemExit(main())
