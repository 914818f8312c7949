"""Work away from the page: the job pool's worker processes and what runs in them, the data a
background job returns, and how the app's code meets the server's threads."""
